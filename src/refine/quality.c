/* Refine layer: quality and per-label figures of an extracted mesh for the report. */
#include "i2m/quality.h"

#include <math.h>
#include <string.h>

#include "i2m/geometry.h"

/* 1-degree bin of an angle from its cosine, without acos and without unpredictable branches:
 * a table over c in [-1, 1] whose cells are narrower than the gap between two consecutive
 * cos(k deg), so a cell holds at most one bin boundary, settled by one comparison. */
#define BIN_CELLS 65536
typedef struct {
  double cos_deg[181];          /* cos(k deg), k = 0..180 */
  uint8_t bin_at_top[BIN_CELLS]; /* the bin of the cell's upper end */
} angle_bins_t;

static int bin_of_cos_slow(const double *cos_deg, double c)
{
  int b = 0; /* angles in [b, b+1) deg have cos in (cos(b+1), cos(b)] */
  while (b < 179 && c <= cos_deg[b + 1]) b++;
  return b;
}

static void angle_bins_init(angle_bins_t *t)
{
  for (int k = 0; k <= 180; k++) t->cos_deg[k] = cos(k * I2M_PI / 180.0);
  for (int i = 0; i < BIN_CELLS; i++)
    t->bin_at_top[i] = (uint8_t)bin_of_cos_slow(t->cos_deg, -1.0 + 2.0 * (i + 1) / BIN_CELLS);
}

static int angle_bin(const angle_bins_t *t, double c)
{
  int i = (int)((c + 1.0) * (0.5 * BIN_CELLS));
  i = i < 0 ? 0 : i >= BIN_CELLS ? BIN_CELLS - 1 : i;
  int b = t->bin_at_top[i]; /* lower c: larger angle, at most one boundary further */
  return b + (b < 179 && c <= t->cos_deg[b + 1]);
}

/* ---- dihedral bands ---- */

static const double LOW_DEG[I2M_DIHEDRAL_NLOW] = {5, 10, 15, 20}, HIGH_DEG[I2M_DIHEDRAL_NHIGH] = {160, 170};
/* their cosines (a smaller angle has a larger cosine) */
static const double LOW_COS[I2M_DIHEDRAL_NLOW] = {0.99619469809174553, 0.98480775301220806, 0.96592582628906829,
                                                  0.93969262078590838};
static const double HIGH_COS[I2M_DIHEDRAL_NHIGH] = {-0.93969262078590838, -0.98480775301220806};

double i2m_dihedral_low_degrees(int k) { return LOW_DEG[k]; }
double i2m_dihedral_high_degrees(int k) { return HIGH_DEG[k]; }

void i2m_dihedral_bands_add(i2m_dihedral_bands_t *b, const double cs[6])
{
  double maxc = cs[0], minc = cs[0];
  for (int k = 1; k < 6; k++) {
    maxc = cs[k] > maxc ? cs[k] : maxc;
    minc = cs[k] < minc ? cs[k] : minc;
  }
  for (int k = 0; k < I2M_DIHEDRAL_NLOW; k++) b->below[k] += !(maxc <= LOW_COS[k]); /* (NaN: counted as bad) */
  for (int k = 0; k < I2M_DIHEDRAL_NHIGH; k++) b->above[k] += !(minc >= HIGH_COS[k]);
}

void i2m_dihedral_bands_merge(i2m_dihedral_bands_t *a, const i2m_dihedral_bands_t *b)
{
  for (int k = 0; k < I2M_DIHEDRAL_NLOW; k++) a->below[k] += b->below[k];
  for (int k = 0; k < I2M_DIHEDRAL_NHIGH; k++) a->above[k] += b->above[k];
}

/* Dihedral angles and radius-edge ratios of every tet (OpenMP-parallel: per-thread
 * extremes and histograms, merged; angles handled by their cosines). */
static i2m_err_t tet_figures(const i2m_tetmesh_t *m, i2m_quality_t *q)
{
  angle_bins_t *bins = NULL;
  I2M_CALL(i2m_malloc(1, sizeof *bins, &bins));
  angle_bins_init(bins);
  double maxc = -1, minc = 1, maxre = 0;
  int64_t above = 0;
  i2m_progress_t pg;
  i2m_progress_begin_total(&pg, "quality figures", "tets", m->nt);
  I2M_OMP(omp parallel reduction(max : maxc, maxre) reduction(min : minc) reduction(+ : above))
  {
    int64_t hist[180] = {0};
    i2m_dihedral_bands_t bands = {{0}, {0}};
    I2M_OMP(omp for schedule(static))
    for (int64_t t = 0; t < m->nt; t++) {
      if ((t & 65535) == 65535) i2m_progress_add(&pg, 65536); /* (one thread prints, every 2 s) */
      const int32_t *v = m->tet + 4 * t;
      const double *a = m->xyz + 3 * (size_t)v[0], *b = m->xyz + 3 * (size_t)v[1];
      const double *c = m->xyz + 3 * (size_t)v[2], *d = m->xyz + 3 * (size_t)v[3];
      double cs[6];
      i2m_tet_dihedral_cosines(a, b, c, d, cs);
      for (int k = 0; k < 6; k++) {
        maxc = cs[k] > maxc ? cs[k] : maxc; /* smallest angle */
        minc = cs[k] < minc ? cs[k] : minc; /* largest angle */
        hist[angle_bin(bins, cs[k])]++;
      }
      i2m_dihedral_bands_add(&bands, cs);
      double re = i2m_tet_radius_edge(a, b, c, d);
      maxre = re > maxre ? re : maxre;
      above += re > q->ratio_bound * (1 + 1e-9);
    }
    I2M_OMP(omp critical(i2m_quality_hist))
    {
      for (int k = 0; k < 180; k++) q->dihedral_hist[k] += hist[k];
      i2m_dihedral_bands_merge(&q->bands, &bands);
    }
  }
  i2m_progress_end(&pg, m->nt);
  q->min_dihedral = m->nt ? i2m_degrees_of_cosine(maxc) : 0;
  q->max_dihedral = m->nt ? i2m_degrees_of_cosine(minc) : 0;
  q->max_radius_edge = maxre;
  q->n_ratio_above = above;
  i2m_free(&bins);
  return I2M_OK;
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

/* The smallest planar angle of interface triangle f. */
static double facet_angle(const i2m_tetmesh_t *m, int64_t f)
{
  const int32_t *v = m->tri + 3 * f;
  return i2m_tri_min_angle(m->xyz + 3 * (size_t)v[0], m->xyz + 3 * (size_t)v[1], m->xyz + 3 * (size_t)v[2]);
}

static i2m_err_t facet_figures(const i2m_tetmesh_t *m, i2m_quality_t *q)
{
  const double bound = q->facet_bound * (1 - 1e-9);
  double min_angle = 180;
  int64_t below = 0, below_junction = 0;
  I2M_OMP(omp parallel for reduction(min : min_angle) reduction(+ : below) schedule(static))
  for (int64_t f = 0; f < m->ntri; f++) {
    const double ang = facet_angle(m, f);
    min_angle = ang < min_angle ? ang : min_angle;
    below += ang < bound;
  }
  if (below > 0) { /* which of them touch a junction (rare: the target is none below) */
    uint8_t *junction = NULL;
    I2M_CALL(junction_vertices(m, &junction));
    I2M_OMP(omp parallel for reduction(+ : below_junction) schedule(static))
    for (int64_t f = 0; f < m->ntri; f++) {
      const int32_t *v = m->tri + 3 * f;
      if (facet_angle(m, f) < bound) below_junction += junction[v[0]] || junction[v[1]] || junction[v[2]];
    }
    i2m_free(&junction);
  }
  q->min_facet_angle = min_angle;
  q->n_facet_below = below;
  q->n_facet_below_junction = below_junction;
  return I2M_OK;
}

#define LABEL_CHUNKS 64
#define LABEL_CHUNK_MAX_LABELS 1024

/* Volume and number of the tets [t0, t1) per label (q's labels, by value). */
static void label_sums(const i2m_tetmesh_t *m, const i2m_quality_t *q, int64_t t0, int64_t t1, double *vol,
                       int64_t *cnt)
{
  for (int64_t t = t0; t < t1; t++) {
    int lo = 0, hi = q->nlabels - 1; /* label values are sorted: binary search */
    while (lo < hi) {
      int mid = (lo + hi) / 2;
      if (q->labels[mid].value < m->tet_label[t]) lo = mid + 1;
      else hi = mid;
    }
    if (q->labels[lo].value != m->tet_label[t]) continue;
    const int32_t *v = m->tet + 4 * t;
    vol[lo] += (1.0 / 6.0) * fabs(i2m_tet_signed_volume6(m->xyz + 3 * (size_t)v[0], m->xyz + 3 * (size_t)v[1],
                                                         m->xyz + 3 * (size_t)v[2], m->xyz + 3 * (size_t)v[3]));
    cnt[lo]++;
  }
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
  if (q->nlabels == 0) return I2M_OK;
  /* fixed chunks, each summed in order, then the chunks in order: the same volumes on any
   * number of threads (one chunk when there are too many labels for per-chunk sums) */
  const int nchunks = q->nlabels <= LABEL_CHUNK_MAX_LABELS ? LABEL_CHUNKS : 1;
  double *vol = NULL;
  int64_t *cnt = NULL;
  i2m_err_t err = i2m_calloc((size_t)nchunks * (size_t)q->nlabels, sizeof *vol, &vol);
  if (err == I2M_OK) err = i2m_calloc((size_t)nchunks * (size_t)q->nlabels, sizeof *cnt, &cnt);
  if (err == I2M_OK) {
    I2M_OMP(omp parallel for schedule(dynamic, 1))
    for (int c = 0; c < nchunks; c++)
      label_sums(m, q, m->nt * c / nchunks, m->nt * (c + 1) / nchunks, vol + (size_t)c * (size_t)q->nlabels,
                 cnt + (size_t)c * (size_t)q->nlabels);
    for (int c = 0; c < nchunks; c++)
      for (int l = 0; l < q->nlabels; l++) {
        q->labels[l].volume += vol[(size_t)c * (size_t)q->nlabels + (size_t)l];
        q->labels[l].ntets += cnt[(size_t)c * (size_t)q->nlabels + (size_t)l];
      }
  }
  i2m_free(&vol);
  i2m_free(&cnt);
  return err;
}

i2m_err_t i2m_quality_compute(const i2m_tetmesh_t *m, const i2m_image_t *img, double ratio_bound,
                              double facet_bound, i2m_quality_t *q)
{
  memset(q, 0, sizeof *q);
  q->ratio_bound = ratio_bound;
  q->facet_bound = facet_bound;
  I2M_CALL(tet_figures(m, q));
  I2M_CALL(facet_figures(m, q));
  I2M_CALL(label_figures(m, img, q));
  return I2M_OK;
}

void i2m_quality_free(i2m_quality_t *q)
{
  i2m_free(&q->labels);
  q->nlabels = 0;
}
