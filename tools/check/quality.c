/* i2m-check: quality figures.  Per tetrahedron: the six dihedral angles (pi minus the angle
 * between the outward normals of the two faces at an edge, by atan2 for accuracy) into a 1
 * degree histogram; the radius-edge ratio (circumradius / shortest edge) with percentiles.
 * Per interface triangle (derived from the tetrahedra): the smallest planar angle. */
#include "check.h"

#include <math.h>
#include <string.h>

static void sub(const double *a, const double *b, double *r)
{
  r[0] = a[0] - b[0];
  r[1] = a[1] - b[1];
  r[2] = a[2] - b[2];
}
static void cross(const double *a, const double *b, double *r)
{
  r[0] = a[1] * b[2] - a[2] * b[1];
  r[1] = a[2] * b[0] - a[0] * b[2];
  r[2] = a[0] * b[1] - a[1] * b[0];
}
static double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Dihedral angles (degrees) at the six edges of tet p[4]; returns 0 for a degenerate tet. */
static int dihedrals(const double *p[4], double ang[6])
{
  static const int FACE[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  static const int EDGE_OPP[6][2] = {{2, 3}, {1, 3}, {1, 2}, {0, 3}, {0, 2}, {0, 1}};
  double n[4][3];
  for (int f = 0; f < 4; f++) {
    double u[3], v[3];
    sub(p[FACE[f][1]], p[FACE[f][0]], u);
    sub(p[FACE[f][2]], p[FACE[f][0]], v);
    cross(u, v, n[f]);
    if (dot(n[f], n[f]) == 0.0) return 0;
  }
  /* edge (i,j) lies on the faces opposite k and l, the two other vertices */
  for (int e = 0; e < 6; e++) {
    const double *a = n[EDGE_OPP[e][0]], *b = n[EDGE_OPP[e][1]];
    double c[3];
    cross(a, b, c);
    ang[e] = 180.0 - atan2(sqrt(dot(c, c)), dot(a, b)) * 180.0 / CK_PI;
  }
  return 1;
}

/* Circumradius / shortest edge; INFINITY for a degenerate tet. */
static double radius_edge(const double *p[4])
{
  double cen[3];
  if (!ck_circumcentre_offset(p[0], p[1], p[2], p[3], cen)) return INFINITY;
  double r = sqrt(dot(cen, cen));
  double emin = INFINITY;
  for (int i = 0; i < 4; i++)
    for (int j = i + 1; j < 4; j++) {
      double e[3];
      sub(p[i], p[j], e);
      double l = dot(e, e);
      if (l < emin) emin = l;
    }
  return emin > 0 ? r / sqrt(emin) : INFINITY;
}

/* The figures of tets [lo, hi) into *q (zeroed but for the extremes' starting values), their
 * ratios into ratio[]; *sum and *nfin: the finite ratios' sum and count. */
static void tet_range(const ck_mesh_t *m, int64_t lo_t, int64_t hi_t, double *ratio, ck_quality_t *q, double *sum,
                      int64_t *nfin)
{
  static const double below[4] = {5.0, 10.0, 15.0, 20.0}, above[2] = {160.0, 170.0};
  for (int64_t t = lo_t; t < hi_t; t++) {
    const double *p[4];
    for (int i = 0; i < 4; i++) p[i] = m->xyz + 3 * m->tet[4 * t + i];
    double q4[4][3];
    ck_tet_normalized(p, q4);
    for (int i = 0; i < 4; i++) p[i] = q4[i];
    double ang[6], lo = 180.0, hi = 0.0;
    if (!dihedrals(p, ang)) {
      ang[0] = ang[1] = ang[2] = 0.0;
      ang[3] = ang[4] = ang[5] = 180.0;
    }
    for (int e = 0; e < 6; e++) {
      int bin = ang[e] >= 0.0 && ang[e] < (double)CK_HIST_BINS ? (int)ang[e] : 0;
      if (ang[e] >= (double)CK_HIST_BINS) bin = CK_HIST_BINS - 1;
      q->dihedral_hist[bin]++;
      if (ang[e] < lo) lo = ang[e];
      if (ang[e] > hi) hi = ang[e];
    }
    for (int k = 0; k < 4; k++) q->dihedral_below[k] += !ck_meets_min(lo, below[k]); /* (NaN counts as below) */
    for (int k = 0; k < 2; k++) q->dihedral_above[k] += !ck_meets_max(hi, above[k]);
    if (lo < q->min_dihedral || t == 0) { /* (the first tet of the mesh in any case, as one loop did) */
      q->min_dihedral = lo;
      q->min_dihedral_tet = t;
    }
    if (hi > q->max_dihedral || t == 0) {
      q->max_dihedral = hi;
      q->max_dihedral_tet = t;
    }
    ratio[t] = radius_edge(p);
    if (q->max_ratio_tet < 0 || ratio[t] > q->max_ratio || (isnan(ratio[t]) && !isnan(q->max_ratio))) {
      q->max_ratio = ratio[t];
      q->max_ratio_tet = t;
    }
    if (!ck_meets_max(ratio[t], q->ratio_bound)) q->ratio_above_bound++; /* (a NaN figure fails every bound) */
    if (!ck_meets_max(ratio[t], 2.0)) q->ratio_above_2++;
    if (isfinite(ratio[t])) {
      *sum += ratio[t];
      (*nfin)++;
    }
  }
}

/* The figures of chunk c after those of the chunks before it (as one loop over the tets would
 * find them: the first extreme kept on ties, a NaN ratio first). */
static void tet_merge(ck_quality_t *q, const ck_quality_t *c)
{
  for (int b = 0; b < CK_HIST_BINS; b++) q->dihedral_hist[b] += c->dihedral_hist[b];
  for (int k = 0; k < 4; k++) q->dihedral_below[k] += c->dihedral_below[k];
  for (int k = 0; k < 2; k++) q->dihedral_above[k] += c->dihedral_above[k];
  if (c->min_dihedral_tet >= 0 && (q->min_dihedral_tet < 0 || c->min_dihedral < q->min_dihedral)) {
    q->min_dihedral = c->min_dihedral;
    q->min_dihedral_tet = c->min_dihedral_tet;
  }
  if (c->max_dihedral_tet >= 0 && (q->max_dihedral_tet < 0 || c->max_dihedral > q->max_dihedral)) {
    q->max_dihedral = c->max_dihedral;
    q->max_dihedral_tet = c->max_dihedral_tet;
  }
  if (c->max_ratio_tet >= 0 && (q->max_ratio_tet < 0 || c->max_ratio > q->max_ratio ||
                                (isnan(c->max_ratio) && !isnan(q->max_ratio)))) {
    q->max_ratio = c->max_ratio;
    q->max_ratio_tet = c->max_ratio_tet;
  }
  q->ratio_above_bound += c->ratio_above_bound;
  q->ratio_above_2 += c->ratio_above_2;
}

/* Dihedral angles and radius-edge ratios of every tet, in fixed chunks on the threads. */
static i2m_err_t tet_quality(const ck_mesh_t *m, double *ratio, ck_quality_t *q)
{
  ck_quality_t *part = NULL;
  double sum[CK_CHUNKS] = {0};
  int64_t nfin[CK_CHUNKS] = {0};
  I2M_CALL(i2m_calloc(CK_CHUNKS, sizeof *part, &part));
  ck_progress_t pr;
  ck_progress_begin(&pr, "quality, dihedral angles and radius-edge ratios", "tets", m->nt);
  CK_OMP("omp parallel for schedule(dynamic, 1)")
  for (int c = 0; c < CK_CHUNKS; c++) {
    ck_quality_t *x = &part[c];
    x->ratio_bound = q->ratio_bound;
    x->min_dihedral = 180.0;
    x->min_dihedral_tet = x->max_dihedral_tet = x->max_ratio_tet = -1;
    const int64_t lo = ck_chunk_begin(m->nt, c), hi = ck_chunk_begin(m->nt, c + 1);
    tet_range(m, lo, hi, ratio, x, &sum[c], &nfin[c]);
    ck_progress_add(&pr, hi - lo);
  }
  q->min_dihedral = 180.0;
  q->max_dihedral = 0.0;
  q->min_dihedral_tet = q->max_dihedral_tet = q->max_ratio_tet = -1;
  double total = 0.0;
  int64_t n = 0;
  for (int c = 0; c < CK_CHUNKS; c++) {
    tet_merge(q, &part[c]);
    total += sum[c];
    n += nfin[c];
  }
  q->ratio_mean = n ? total / (double)n : 0.0;
  i2m_free(&part);
  ck_progress_set(&pr, m->nt);
  ck_progress_end(&pr);
  return I2M_OK;
}

/* The smallest planar angle of the interface triangles, in fixed chunks on the threads. */
static void planar_angles(const ck_mesh_t *m, const ck_iface_t *f, ck_quality_t *q)
{
  double amin[CK_CHUNKS];
  int64_t tmin[CK_CHUNKS], b30[CK_CHUNKS] = {0}, bb[CK_CHUNKS] = {0};
  const double facet_bound = q->facet_angle_bound;
  CK_OMP("omp parallel for schedule(dynamic, 4)")
  for (int c = 0; c < CK_CHUNKS; c++) {
    amin[c] = 180.0;
    tmin[c] = -1;
    for (int64_t i = ck_chunk_begin(f->n, c); i < ck_chunk_begin(f->n, c + 1); i++) {
      const int32_t *v = f->v + 3 * i;
      double a = ck_min_angle_deg(m->xyz + 3 * v[0], m->xyz + 3 * v[1], m->xyz + 3 * v[2]);
      if (a < amin[c]) {
        amin[c] = a;
        tmin[c] = i;
      }
      b30[c] += !ck_meets_min(a, 30.0);
      bb[c] += !ck_meets_min(a, facet_bound);
    }
  }
  q->ntri = f->n;
  q->min_planar_angle = f->n ? 180.0 : 0.0;
  q->min_planar_tri = -1;
  for (int c = 0; c < CK_CHUNKS; c++) {
    if (tmin[c] >= 0 && amin[c] < q->min_planar_angle) {
      q->min_planar_angle = amin[c];
      q->min_planar_tri = tmin[c];
    }
    q->planar_below_30 += b30[c];
    q->planar_below_bound += bb[c];
  }
}

i2m_err_t ck_quality(const ck_mesh_t *m, const ck_topo_t *topo, double ratio_bound,
                     double facet_bound, ck_quality_t *q)
{
  double *ratio = NULL;
  memset(q, 0, sizeof *q);
  q->ratio_bound = ratio_bound;
  q->facet_angle_bound = facet_bound;
  I2M_CALL(i2m_malloc((size_t)m->nt, sizeof *ratio, &ratio));
  i2m_err_t err = tet_quality(m, ratio, q);
  if (err == I2M_OK) {
    q->ratio_p50 = ck_percentile(ratio, m->nt, 0.50);
    q->ratio_p90 = ck_percentile(ratio, m->nt, 0.90);
    q->ratio_p99 = ck_percentile(ratio, m->nt, 0.99);
    q->ratio_p999 = ck_percentile(ratio, m->nt, 0.999);
    planar_angles(m, &topo->iface, q);
  }
  i2m_free(&ratio);
  return err;
}
