/* i2m-check: the checker's own geometry.  An exact orientation test (a floating-point
 * filter, then exact expansion arithmetic after Shewchuk's two-sum / two-product), distances
 * from a point to a triangle, planar angles, percentiles, a uniform grid of buckets.
 * Deliberately independent of src/geom.  Compiled with -ffp-contract=off (project-wide FPFLAGS). */
#include "check.h"

#include <float.h>
#include <math.h>
#include <string.h>

/* ---- exact expansions: increasing magnitude, non-overlapping, zeros eliminated ---- */
static void two_sum(double a, double b, double *x, double *y)
{
  *x = a + b;
  double bv = *x - a, av = *x - bv;
  *y = (a - av) + (b - bv);
}

static void split(double a, double *hi, double *lo)
{
  double c = 134217729.0 * a; /* 2^27 + 1 */
  double big = c - a;
  *hi = c - big;
  *lo = a - *hi;
}

static void two_product(double a, double b, double *x, double *y)
{
  *x = a * b;
  double ah, al, bh, bl;
  split(a, &ah, &al);
  split(b, &bh, &bl);
  double err = *x - ah * bh - al * bh - ah * bl;
  *y = al * bl - err;
}

/* h = e + b; returns length.  h may not alias e. */
static int grow(int n, const double *e, double b, double *h)
{
  double q = b, hh;
  int k = 0;
  for (int i = 0; i < n; i++) {
    two_sum(q, e[i], &q, &hh);
    if (hh != 0.0) h[k++] = hh;
  }
  if (q != 0.0 || k == 0) h[k++] = q;
  return k;
}

/* h = e + f (repeated growth); scratch t must hold n+m values. */
static int exp_sum(int n, const double *e, int m, const double *f, double *h, double *t)
{
  int k = n;
  for (int i = 0; i < n; i++) h[i] = e[i];
  for (int j = 0; j < m; j++) {
    k = grow(k, h, f[j], t);
    for (int i = 0; i < k; i++) h[i] = t[i];
  }
  return k;
}

/* h = e * b; h holds 2n values. */
static int scale(int n, const double *e, double b, double *h, double *t)
{
  int k = 0;
  double tmp[2], acc[64];
  int na = 0;
  for (int i = 0; i < n; i++) {
    two_product(e[i], b, &tmp[1], &tmp[0]);
    int l = exp_sum(na, acc, 2, tmp, h, t);
    for (int j = 0; j < l; j++) acc[j] = h[j];
    na = l;
  }
  for (k = 0; k < na; k++) h[k] = acc[k];
  if (na == 0) h[na++] = 0.0;
  return na;
}

/* h = e * f for short expansions (n, m <= 8). */
static int exp_mul(int n, const double *e, int m, const double *f, double *h)
{
  double part[64], t[128], acc[64], s[128];
  int na = 0;
  for (int j = 0; j < m; j++) {
    int l = scale(n, e, f[j], part, t);
    na = exp_sum(na, acc, l, part, s, t);
    for (int i = 0; i < na; i++) acc[i] = s[i];
  }
  for (int i = 0; i < na; i++) h[i] = acc[i];
  if (na == 0) h[na++] = 0.0;
  return na;
}

static int exact_orient(const double a[3], const double b[3], const double c[3], const double d[3])
{
  double u[3][2], v[3][2], w[3][2];
  for (int k = 0; k < 3; k++) {
    two_sum(b[k], -a[k], &u[k][1], &u[k][0]);
    two_sum(c[k], -a[k], &v[k][1], &v[k][0]);
    two_sum(d[k], -a[k], &w[k][1], &w[k][0]);
  }
  /* det = sum over permutations (i,j,k) of sign * u_i v_j w_k */
  static const int perm[6][4] = {{0, 1, 2, 1}, {1, 2, 0, 1}, {2, 0, 1, 1},
                                 {0, 2, 1, -1}, {1, 0, 2, -1}, {2, 1, 0, -1}};
  double acc[256], s[512], t[512];
  int na = 0;
  for (int p = 0; p < 6; p++) {
    double uv[16], uvw[64];
    int l1 = exp_mul(2, u[perm[p][0]], 2, v[perm[p][1]], uv);
    int l2 = exp_mul(l1, uv, 2, w[perm[p][2]], uvw);
    if (perm[p][3] < 0)
      for (int i = 0; i < l2; i++) uvw[i] = -uvw[i];
    na = exp_sum(na, acc, l2, uvw, s, t);
    for (int i = 0; i < na; i++) acc[i] = s[i];
  }
  for (int i = na - 1; i >= 0; i--)
    if (acc[i] != 0.0) return acc[i] > 0 ? 1 : -1;
  return 0;
}

double ck_volume6(const double a[3], const double b[3], const double c[3], const double d[3])
{
  double u[3], v[3], w[3];
  for (int k = 0; k < 3; k++) {
    u[k] = b[k] - a[k];
    v[k] = c[k] - a[k];
    w[k] = d[k] - a[k];
  }
  return u[0] * (v[1] * w[2] - v[2] * w[1]) + u[1] * (v[2] * w[0] - v[0] * w[2]) +
         u[2] * (v[0] * w[1] - v[1] * w[0]);
}

/* The exponent of x, clamped so that 2^-e stays a finite normal number (x may be subnormal). */
static int pow2_exponent(double x)
{
  const int e = ilogb(x);
  return e < -1000 ? -1000 : e > 1000 ? 1000 : e;
}

/* The largest magnitude of the four points' coordinates. */
static double max_coordinate(const double *p[4])
{
  double m = 0;
  for (int i = 0; i < 4; i++)
    for (int k = 0; k < 3; k++) m = fmax(m, fabs(p[i][k]));
  return m;
}

/* Far from 1 (products of three coordinates would overflow or underflow): the points are
 * scaled by a power of two, which is exact and keeps the sign of the determinant. */
#define ORIENT_RANGE 0x1p250

int ck_orient3d(const double a[3], const double b[3], const double c[3], const double d[3])
{
  const double *pts[4] = {a, b, c, d};
  const double big = max_coordinate(pts);
  if (isfinite(big) && (big > ORIENT_RANGE || (big > 0 && big < 1.0 / ORIENT_RANGE))) {
    const double scale = ldexp(1.0, -pow2_exponent(big));
    double q[4][3];
    for (int i = 0; i < 4; i++)
      for (int k = 0; k < 3; k++) q[i][k] = pts[i][k] * scale;
    return ck_orient3d(q[0], q[1], q[2], q[3]);
  }
  double u[3], v[3], w[3];
  for (int k = 0; k < 3; k++) {
    u[k] = b[k] - a[k];
    v[k] = c[k] - a[k];
    w[k] = d[k] - a[k];
  }
  double det = u[0] * (v[1] * w[2] - v[2] * w[1]) + u[1] * (v[2] * w[0] - v[0] * w[2]) +
               u[2] * (v[0] * w[1] - v[1] * w[0]);
  double perm = fabs(u[0]) * (fabs(v[1] * w[2]) + fabs(v[2] * w[1])) +
                fabs(u[1]) * (fabs(v[2] * w[0]) + fabs(v[0] * w[2])) +
                fabs(u[2]) * (fabs(v[0] * w[1]) + fabs(v[1] * w[0]));
  double bound = 1.0e-15 * perm; /* > Shewchuk's (7 + 56 eps) eps */
  if (det > bound) return 1;
  if (-det > bound) return -1;
  if (!isfinite(det)) return 0;
  return exact_orient(a, b, c, d);
}

void ck_tet_normalized(const double *p[4], double q[4][3])
{
  double m = 0;
  for (int i = 1; i < 4; i++)
    for (int k = 0; k < 3; k++) m = fmax(m, fabs(p[i][k] - p[0][k]));
  const double scale = m > 0 && isfinite(m) ? ldexp(1.0, -pow2_exponent(m)) : 1.0; /* (a power of two: exact) */
  for (int i = 0; i < 4; i++)
    for (int k = 0; k < 3; k++) q[i][k] = (p[i][k] - p[0][k]) * scale;
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

double ck_dist2_point_triangle(const double p[3], const double a[3], const double b[3],
                               const double c[3])
{
  /* Regions of the triangle (Ericson, Real-Time Collision Detection, 5.1.5), written here. */
  double ab[3], ac[3], ap[3], q[3];
  for (int k = 0; k < 3; k++) {
    ab[k] = b[k] - a[k];
    ac[k] = c[k] - a[k];
    ap[k] = p[k] - a[k];
  }
  double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
  if (d1 <= 0 && d2 <= 0) { for (int k = 0; k < 3; k++) q[k] = a[k]; goto done; }
  double bp[3];
  for (int k = 0; k < 3; k++) bp[k] = p[k] - b[k];
  double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
  if (d3 >= 0 && d4 <= d3) { for (int k = 0; k < 3; k++) q[k] = b[k]; goto done; }
  double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    double t = d1 / (d1 - d3);
    for (int k = 0; k < 3; k++) q[k] = a[k] + t * ab[k];
    goto done;
  }
  double cp[3];
  for (int k = 0; k < 3; k++) cp[k] = p[k] - c[k];
  double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
  if (d6 >= 0 && d5 <= d6) { for (int k = 0; k < 3; k++) q[k] = c[k]; goto done; }
  double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    double t = d2 / (d2 - d6);
    for (int k = 0; k < 3; k++) q[k] = a[k] + t * ac[k];
    goto done;
  }
  double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    for (int k = 0; k < 3; k++) q[k] = b[k] + t * (c[k] - b[k]);
    goto done;
  }
  {
    double den = va + vb + vc;
    if (!(den > 0)) { /* degenerate triangle: nearest of the three edges' ends */
      double m = DBL_MAX;
      const double *v3[3] = {a, b, c};
      for (int i = 0; i < 3; i++) {
        double dd = 0;
        for (int k = 0; k < 3; k++) dd += (p[k] - v3[i][k]) * (p[k] - v3[i][k]);
        if (dd < m) m = dd;
      }
      return m;
    }
    double v = vb / den, w = vc / den;
    for (int k = 0; k < 3; k++) q[k] = a[k] + ab[k] * v + ac[k] * w;
  }
done:;
  double d = 0;
  for (int k = 0; k < 3; k++) d += (p[k] - q[k]) * (p[k] - q[k]);
  return d;
}

int ck_circumcentre_offset(const double p0[3], const double p1[3], const double p2[3], const double p3[3], double off[3])
{
  double b[3], c[3], d[3];
  for (int k = 0; k < 3; k++) {
    b[k] = p1[k] - p0[k];
    c[k] = p2[k] - p0[k];
    d[k] = p3[k] - p0[k];
  }
  const double cd[3] = {c[1] * d[2] - c[2] * d[1], c[2] * d[0] - c[0] * d[2], c[0] * d[1] - c[1] * d[0]};
  const double db[3] = {d[1] * b[2] - d[2] * b[1], d[2] * b[0] - d[0] * b[2], d[0] * b[1] - d[1] * b[0]};
  const double bc[3] = {b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]};
  const double den = 2.0 * dot3(b, cd);
  if (den == 0.0) return 0;
  const double bb = dot3(b, b), cc = dot3(c, c), dd = dot3(d, d);
  for (int k = 0; k < 3; k++) off[k] = (bb * cd[k] + cc * db[k] + dd * bc[k]) / den;
  return 1;
}

int ck_circumcentre(const double p0[3], const double p1[3], const double p2[3], const double p3[3], double cen[3])
{
  if (!ck_circumcentre_offset(p0, p1, p2, p3, cen)) return 0;
  for (int k = 0; k < 3; k++) cen[k] += p0[k];
  return 1;
}

double ck_min_angle_deg(const double a[3], const double b[3], const double c[3])
{
  const double *t[4] = {a, b, c, c};
  double n[4][3];
  ck_tet_normalized(t, n); /* (the triangle as a flat tet: angles at any magnitude) */
  const double *v[3] = {n[0], n[1], n[2]};
  double m = 180.0;
  for (int i = 0; i < 3; i++) {
    const double *o = v[i], *p = v[(i + 1) % 3], *q = v[(i + 2) % 3];
    double x[3], y[3], cr[3];
    for (int k = 0; k < 3; k++) {
      x[k] = p[k] - o[k];
      y[k] = q[k] - o[k];
    }
    cr[0] = x[1] * y[2] - x[2] * y[1];
    cr[1] = x[2] * y[0] - x[0] * y[2];
    cr[2] = x[0] * y[1] - x[1] * y[0];
    double ang = atan2(sqrt(dot3(cr, cr)), dot3(x, y)) * 180.0 / CK_PI;
    if (ang < m) m = ang;
  }
  return m;
}

double ck_percentile(double *a, int64_t n, double q)
{
  if (n <= 0) return 0.0;
  int64_t k = (int64_t)ceil(q * (double)n) - 1;
  if (k < 0) k = 0;
  if (k >= n) k = n - 1;
  int64_t lo = 0, hi = n - 1;
  while (lo < hi) { /* quickselect, median of three */
    int64_t mid = lo + (hi - lo) / 2;
    double x = a[lo], y = a[mid], z = a[hi];
    double piv = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
    int64_t i = lo, j = hi;
    while (i <= j) {
      while (a[i] < piv) i++;
      while (a[j] > piv) j--;
      if (i <= j) {
        double t = a[i];
        a[i] = a[j];
        a[j] = t;
        i++;
        j--;
      }
    }
    if (k <= j)
      hi = j;
    else if (k >= i)
      lo = i;
    else
      break;
  }
  return a[k];
}

/* ---- a uniform grid of buckets over items with bounding boxes ---- */
/* The cells item i's box meets: c0..c1 along each axis. */
static void item_cells(const ck_grid_t *g, ck_bbox_fn bbox, const void *ctx, int64_t i, int64_t c0[3], int64_t c1[3])
{
  double lo[3], hi[3];
  bbox(ctx, i, lo, hi);
  for (int a = 0; a < 3; a++) {
    c0[a] = ck_grid_cell(g, a, lo[a]);
    c1[a] = ck_grid_cell(g, a, hi[a]);
  }
}

i2m_err_t ck_grid_build(ck_grid_t *g, int64_t nitems, ck_bbox_fn bbox, const void *ctx, ck_progress_t *pr)
{
  const int64_t ncell = g->n[0] * g->n[1] * g->n[2];
  int64_t *next = NULL;
  g->nitems = nitems;
  I2M_CALL(i2m_calloc((size_t)ncell + 1, sizeof *g->start, &g->start));
  for (int pass = 0; pass < 2; pass++) {
    if (pass == 1) { /* counts to starts; next: where each cell's next item goes */
      for (int64_t c = 0; c < ncell; c++) g->start[c + 1] += g->start[c];
      I2M_CALL(i2m_malloc((size_t)g->start[ncell] + 1, sizeof *g->item, &g->item));
      I2M_CALL(i2m_malloc((size_t)ncell + 1, sizeof *next, &next));
      memcpy(next, g->start, (size_t)(ncell + 1) * sizeof *next);
    }
    CK_OMP("omp parallel for schedule(dynamic, 1)")
    for (int k = 0; k < CK_CHUNKS; k++) {
      const int64_t i0 = ck_chunk_begin(nitems, k), i1 = ck_chunk_begin(nitems, k + 1);
      for (int64_t i = i0; i < i1; i++) {
        int64_t c0[3], c1[3];
        item_cells(g, bbox, ctx, i, c0, c1);
        for (int64_t z = c0[2]; z <= c1[2]; z++)
          for (int64_t y = c0[1]; y <= c1[1]; y++)
            for (int64_t x = c0[0]; x <= c1[0]; x++) {
              const int64_t c = (z * g->n[1] + y) * g->n[0] + x;
              if (pass == 0) {
                CK_OMP("omp atomic")
                g->start[c + 1]++;
              } else {
                int64_t at;
                CK_OMP("omp atomic capture")
                at = next[c]++;
                g->item[at] = i;
              }
            }
      }
      if (pr) ck_progress_add(pr, i1 - i0);
    }
  }
  i2m_free(&next);
  return I2M_OK;
}

void ck_grid_free(ck_grid_t *g)
{
  i2m_free(&g->start);
  i2m_free(&g->item);
}
