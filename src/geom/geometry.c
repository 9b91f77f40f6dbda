/* Geometry layer: circumcentres and quality measures in double precision (REFERENCE §3.7). */
#include "i2m/geometry.h"

#include "expansion.h"

#include <math.h>

/* ---- double-double arithmetic (about 106 bits) from the error-free transformations, for
 * the circumcentres of nearly flat tets, whose plain evaluation loses every digit ---- */
typedef struct {
  double hi, lo;
} dd_t;

static dd_t dd_norm(double hi, double lo)
{
  dd_t r;
  i2m_ex_fast_two_sum(hi, lo, &r.hi, &r.lo);
  return r;
}
static dd_t dd_add(dd_t a, dd_t b)
{
  double s, e;
  i2m_ex_two_sum(a.hi, b.hi, &s, &e);
  return dd_norm(s, e + a.lo + b.lo);
}
static dd_t dd_neg(dd_t a) { return (dd_t){-a.hi, -a.lo}; }
static dd_t dd_sub(dd_t a, dd_t b) { return dd_add(a, dd_neg(b)); }
static dd_t dd_mul(dd_t a, dd_t b)
{
  double p, e;
  i2m_ex_two_product(a.hi, b.hi, &p, &e);
  return dd_norm(p, e + a.hi * b.lo + a.lo * b.hi);
}
static dd_t dd_diff(double a, double b) /* a - b, exactly */
{
  double x = a - b;
  return dd_norm(x, i2m_ex_two_diff_tail(a, b, x));
}
static double dd_div(dd_t a, dd_t b) /* to double precision */
{
  double q1 = a.hi / b.hi;
  dd_t r = dd_sub(a, dd_mul((dd_t){q1, 0}, b));
  return q1 + r.hi / b.hi;
}

/* c - a = (|u|^2 (v x w) + |v|^2 (w x u) + |w|^2 (u x v)) / (2 u.(v x w)) in double-double. */
static int circumcenter_dd(const double a[3], const double b[3], const double c[3], const double d[3], double cc[3],
                           double *r2)
{
  dd_t u[3], v[3], w[3], lu = {0, 0}, lv = {0, 0}, lw = {0, 0};
  for (int k = 0; k < 3; k++) {
    u[k] = dd_diff(b[k], a[k]);
    v[k] = dd_diff(c[k], a[k]);
    w[k] = dd_diff(d[k], a[k]);
    lu = dd_add(lu, dd_mul(u[k], u[k]));
    lv = dd_add(lv, dd_mul(v[k], v[k]));
    lw = dd_add(lw, dd_mul(w[k], w[k]));
  }
  dd_t vw[3], wu[3], uv[3], den = {0, 0};
  for (int k = 0; k < 3; k++) {
    int i = (k + 1) % 3, j = (k + 2) % 3;
    vw[k] = dd_sub(dd_mul(v[i], w[j]), dd_mul(v[j], w[i]));
    wu[k] = dd_sub(dd_mul(w[i], u[j]), dd_mul(w[j], u[i]));
    uv[k] = dd_sub(dd_mul(u[i], v[j]), dd_mul(u[j], v[i]));
  }
  for (int k = 0; k < 3; k++) den = dd_add(den, dd_mul(u[k], vw[k]));
  den = dd_add(den, den);
  if (den.hi == 0) return -1;
  double x[3];
  for (int k = 0; k < 3; k++) {
    dd_t num = dd_add(dd_add(dd_mul(lu, vw[k]), dd_mul(lv, wu[k])), dd_mul(lw, uv[k]));
    x[k] = dd_div(num, den);
    cc[k] = a[k] + x[k];
  }
  *r2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
  return isfinite(*r2) ? 0 : -1;
}

int i2m_tet_circumcenter_flat(const double a[3], const double b[3], const double c[3], const double d[3],
                              double cc[3], double *r2)
{
  if (circumcenter_dd(a, b, c, d, cc, r2) == 0) return 0;
  cc[0] = cc[1] = cc[2] = 1e300;
  *r2 = INFINITY;
  return -1;
}

double i2m_tet_signed_volume6(const double a[3], const double b[3], const double c[3], const double d[3])
{
  double u[3], v[3], w[3], vw[3];
  i2m_sub3(b, a, u);
  i2m_sub3(c, a, v);
  i2m_sub3(d, a, w);
  i2m_cross3(v, w, vw);
  return i2m_dot3(u, vw);
}

double i2m_tet_min_edge2(const double a[3], const double b[3], const double c[3], const double d[3])
{
  const double *p[4] = {a, b, c, d};
  double m = INFINITY;
  for (int i = 0; i < 4; i++)
    for (int j = i + 1; j < 4; j++) {
      double l = i2m_dist2(p[i], p[j]);
      if (l < m) m = l;
    }
  return m;
}

double i2m_tet_radius_edge(const double a[3], const double b[3], const double c[3], const double d[3])
{
  double cc[3], r2;
  if (i2m_tet_circumcenter(a, b, c, d, cc, &r2) != 0) return INFINITY;
  return sqrt(r2 / i2m_tet_min_edge2(a, b, c, d));
}

/* The face normals of tet abcd, not normalised (outward for a positive tet), face k opposite
 * vertex k, and their squared lengths. */
static void face_normals(const double a[3], const double b[3], const double c[3], const double d[3], double n[4][3],
                         double len2[4])
{
  const double *p[4] = {a, b, c, d};
  static const int fv[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  for (int f = 0; f < 4; f++) {
    double e1[3], e2[3];
    i2m_sub3(p[fv[f][1]], p[fv[f][0]], e1);
    i2m_sub3(p[fv[f][2]], p[fv[f][0]], e2);
    i2m_cross3(e1, e2, n[f]);
    len2[f] = i2m_dot3(n[f], n[f]);
  }
}

/* The dihedral angle at edge (i,j) is between the faces opposite the other two vertices:
 * edges ab, ac, ad, bc, bd, cd <-> face pairs (2,3), (1,3), (1,2), (0,3), (0,2), (0,1). */
static const int EDGE_FACES[6][2] = {{2, 3}, {1, 3}, {1, 2}, {0, 3}, {0, 2}, {0, 1}};

void i2m_tet_dihedral_cosines(const double a[3], const double b[3], const double c[3], const double d[3],
                              double cosines[6])
{
  double n[4][3], len2[4];
  face_normals(a, b, c, d, n, len2);
  for (int f = 0; f < 4; f++) {
    const double l = sqrt(len2[f]);
    if (l > 0) {
      const double inv = 1.0 / l; /* (one division, not three) */
      for (int k = 0; k < 3; k++) n[f][k] *= inv;
    }
  }
  for (int e = 0; e < 6; e++) {
    double cs = -i2m_dot3(n[EDGE_FACES[e][0]], n[EDGE_FACES[e][1]]);
    cosines[e] = cs > 1 ? 1 : cs < -1 ? -1 : cs;
  }
}

void i2m_tet_dihedral_terms(const double a[3], const double b[3], const double c[3], const double d[3], double num[6],
                            double den2[6])
{
  double n[4][3], len2[4];
  face_normals(a, b, c, d, n, len2);
  for (int e = 0; e < 6; e++) {
    const int i = EDGE_FACES[e][0], j = EDGE_FACES[e][1];
    num[e] = -i2m_dot3(n[i], n[j]);
    den2[e] = len2[i] * len2[j];
  }
}

void i2m_tet_dihedral_angles(const double a[3], const double b[3], const double c[3], const double d[3],
                             double angles[6])
{
  double cs[6];
  i2m_tet_dihedral_cosines(a, b, c, d, cs);
  for (int e = 0; e < 6; e++) angles[e] = i2m_degrees_of_cosine(cs[e]);
}

double i2m_tet_max_dihedral_cosine(const double a[3], const double b[3], const double c[3], const double d[3])
{
  double cs[6], cmax = -1.0;
  i2m_tet_dihedral_cosines(a, b, c, d, cs);
  for (int e = 0; e < 6; e++) cmax = cs[e] > cmax ? cs[e] : cmax;
  return cmax;
}

double i2m_tet_min_dihedral(const double a[3], const double b[3], const double c[3], const double d[3])
{
  return i2m_degrees_of_cosine(i2m_tet_max_dihedral_cosine(a, b, c, d));
}

int i2m_tri_circumcenter(const double a[3], const double b[3], const double c[3], double cc[3],
                         double *r2)
{
  /* c - a = (|u|^2 v - |v|^2 u) x (u x v) / (2 |u x v|^2) */
  double u[3], v[3], uv[3], t[3], x[3];
  i2m_sub3(b, a, u);
  i2m_sub3(c, a, v);
  i2m_cross3(u, v, uv);
  double den = 2.0 * i2m_dot3(uv, uv);
  if (!(den > 0)) {
    cc[0] = cc[1] = cc[2] = 1e300;
    *r2 = INFINITY;
    return -1;
  }
  double lu = i2m_dot3(u, u), lv = i2m_dot3(v, v);
  for (int k = 0; k < 3; k++) t[k] = lu * v[k] - lv * u[k];
  i2m_cross3(t, uv, x);
  for (int k = 0; k < 3; k++) {
    x[k] /= den;
    cc[k] = a[k] + x[k];
  }
  *r2 = i2m_dot3(x, x);
  return 0;
}

double i2m_tri_min_angle(const double a[3], const double b[3], const double c[3])
{
  const double *p[3] = {a, b, c};
  double cmax = -1.0; /* the smallest angle has the largest cosine: one acos */
  for (int i = 0; i < 3; i++) {
    double e1[3], e2[3];
    i2m_sub3(p[(i + 1) % 3], p[i], e1);
    i2m_sub3(p[(i + 2) % 3], p[i], e2);
    double l = sqrt(i2m_dot3(e1, e1) * i2m_dot3(e2, e2));
    if (!(l > 0)) return 0.0;
    double cs = i2m_dot3(e1, e2) / l;
    if (cs > cmax) cmax = cs;
  }
  return i2m_degrees_of_cosine(cmax);
}
