/* i2m geometry layer (layer 1): robust orient2d (projected), orient3d and insphere, and
 * insphere with symbolic perturbation, after Shewchuk's method (DCG 1997).
 *
 * Each predicate is a floating-point filter (the determinant in doubles plus a rigorous
 * error bound = coefficient x permanent, Shewchuk's stage-A bounds) that decides almost
 * every call, followed by an exact evaluation in separate, non-inlined functions:
 *   1. the coordinates are scaled by a power of two (exact) so that the largest one lies in
 *      [2^(T-1), 2^T) for a per-predicate T chosen so that no expansion component overflows
 *      and, for the documented coordinate ratios, no product underflows;
 *   2. if all coordinate differences to a base point are exact (Two-Diff tails all zero,
 *      the usual case for lattice or voxel-grid points) the determinant is evaluated on the
 *      translated points, where the base point is the origin and the formulas shrink to
 *      the 3x3 / 4x4 determinants of the differences;
 *   3. otherwise the full formulas run on the scaled original coordinates (exact 2x2
 *      minors, 3x3 minors, 4x4 orientation determinants and the lifted 5x5 determinant).
 * All expansions live in fixed-size stack buffers sized by the algorithmic bounds: no heap,
 * no globals.
 *
 * Determinant identities used (rows are points, p = (x, y, z), w = |p|^2):
 *   m(p,q)      = px qy - qx py
 *   D(p,q,r)    = det [p; q; r] = pz m(q,r) - qz m(p,r) + rz m(p,q)
 *   O(p,q,r,s)  = det [q-p; r-p; s-p] = -det [p 1; q 1; r 1; s 1]
 *               = D(q,r,s) - D(p,r,s) + D(p,q,s) - D(p,q,r)
 *   I(a,b,c,d,e) = -det [x y z w 1]  (rows a..e)
 *               = -w_a O(b,c,d,e) + w_b O(a,c,d,e) - w_c O(a,b,d,e) + w_d O(a,b,c,e)
 *                 - w_e O(a,b,c,d)
 * I is translation invariant; with e at the origin it is the 4x4 determinant
 *   La D(b,c,d) - Lb D(a,c,d) + Lc D(a,b,d) - Ld D(a,b,c),  Lp = |p - e|^2,  D on p - e,
 * which the filter evaluates.  I > 0 when e is inside the sphere of a positive tet abcd:
 * for e at the circumcentre of the unit tet the four L are r^2 and I = r^2 O(a,b,c,d) > 0. */
#include "i2m/predicates.h"

#include <math.h>

#include "expansion.h"

#if defined(__GNUC__) || defined(__clang__)
#define I2M_COLD __attribute__((noinline, cold))
#else
#define I2M_COLD I2M_NOINLINE
#endif

/* ---- filter constants ------------------------------------------------------------------
 * Stage-A error-bound coefficients (Shewchuk: (3 + 16eps)eps, (7 + 56eps)eps,
 * (16 + 224eps)eps for the same expression trees).  The second-order terms are raised
 * (exactly representable constants) so that they also absorb (i) the rounding of
 * coefficient x permanent and (ii) the absolute errors of products that underflow, which the
 * range checks below keep under eps^2 x permanent:
 *   orient2d: products are not multiplied again: error <= 2 * 2^-1075, needs P >= 2^-900;
 *   orient3d: an underflowed xy-product is multiplied by one z difference: error
 *             <= 2^-1071 max(1, zmax); with zmax <= 2^450 and P >= 2^-500 it is < 2^-606;
 *   insphere: error <= 2^-1067 max(1, S)^1.5 (S = sum of the four lifts, which bounds every
 *             factor); with S <= 2^300 and P >= 2^-500 it is < 2^-606.
 * Outside those ranges (coordinate differences below ~1e-50 or above ~1e45..1e135, or an
 * infinite / NaN permanent after overflow) the filter declines and the exact path decides. */
#define EPS I2M_EX_EPS
#define O2D_BOUND ((3.0 + 32.0 * EPS) * EPS)
#define O2D_PERM_MIN 0x1p-900

/* ---- exact-path scaling ------------------------------------------------------------------
 * Largest scaled coordinate in [2^(T-1), 2^T) (per axis for orient2d and orient3d, whose
 * terms are products of one coordinate per axis).  Worst intermediate magnitudes: orient2d
 * 2^(2T+3), orient3d 2^(3T+6), insphere 2^(5T+12) (all < 2^1023), and every split operand
 * is at most a degree-4 quantity (< 2^(4T+10) < 2^995).  With lowest significant bits at
 * least 2^(T-1-R-52) for coordinates within a factor 2^R of the largest one (of their axis
 * for orient2d / orient3d), products of k coordinates stay above 2^-1074 (no underflow)
 * when k (T - R - 53) >= -1074, i.e.
 *   orient2d R <= 984, orient3d R <= 635, insphere R <= 361
 * (the header documents 2^950, 2^630 and 2^360). */
#define T_O2D 500
#define T_O3D 330
#define T_ISP 200

/* Copies the n points into dst (axes 0..naxes-1; the others are set to 0), multiplied by a
 * power of two so that the largest |coordinate| lies in [2^(T-1), 2^T): one factor for all
 * axes, or with per_axis one factor per axis (orient3d and orient2d are products of one
 * coordinate of each axis, so each column can be scaled on its own; insphere cannot, its
 * lift mixes the axes).  The scaling is exact unless a coordinate underflows (outside the
 * documented ratio).  Returns 0 (the caller answers 0) when a coordinate is not finite or
 * the points are all zero (per_axis: all zero along one axis, which makes the determinant
 * vanish). */
static int scale_points(int n, const double *const *src, int naxes, int T, int per_axis,
                        double (*dst)[3])
{
  double mx[3] = {0.0, 0.0, 0.0};
  for (int i = 0; i < n; i++)
    for (int k = 0; k < naxes; k++) {
      const double v = fabs(src[i][k]);
      if (!(v <= DBL_MAX)) return 0;
      mx[k] = v > mx[k] ? v : mx[k];
    }
  if (!per_axis) {
    for (int k = 1; k < naxes; k++) mx[0] = mx[k] > mx[0] ? mx[k] : mx[0];
    for (int k = 1; k < naxes; k++) mx[k] = mx[0];
  }
  /* factor 2^(T - ex) as the product f1 * f2 of two powers of two, each representable (the
   * shift exceeds 1023 only when scaling up subnormal data, where both steps are exact) */
  double f1[3] = {1.0, 1.0, 1.0}, f2[3] = {1.0, 1.0, 1.0};
  for (int k = 0; k < naxes; k++) {
    int ex;
    if (mx[k] == 0.0) return 0;
    (void)frexp(mx[k], &ex);
    const int shift = T - ex, s1 = shift / 2;
    f1[k] = ldexp(1.0, s1);
    f2[k] = ldexp(1.0, shift - s1);
  }
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) dst[i][k] = k < naxes ? (src[i][k] * f1[k]) * f2[k] : 0.0;
  return 1;
}

/* Translates points 0..n-1 so that point `base` is the origin, if every difference is exact
 * (the translated set then has the same determinants).  Returns 1 if it did. */
static int translate_if_exact(int n, int base, double (*p)[3])
{
  double t[5][3];
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) {
      const double x = p[i][k] - p[base][k];
      if (i2m_ex_two_diff_tail(p[i][k], p[base][k], x) != 0.0) return 0;
      t[i][k] = x;
    }
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) p[i][k] = t[i][k];
  return 1;
}

/* ---- exact determinants on expansions ---------------------------------------------------- */

/* Exact xy-minors m(i,j) = xi yj - xj yi of all pairs i < j of n points (<= 4 components). */
typedef struct {
  double m[5][5][4];
  int len[5][5];
} minors_t;

static void minors_compute(int n, const double (*p)[3], minors_t *mn)
{
  for (int i = 0; i < n; i++)
    for (int j = i + 1; j < n; j++)
      mn->len[i][j] = i2m_ex_two_products_diff(p[i][0], p[j][1], p[j][0], p[i][1], mn->m[i][j]);
}

/* D(i,j,k) = zi m(j,k) - zj m(i,k) + zk m(i,j) for i < j < k; h: 24 components. */
static int det3_exact(const double (*p)[3], const minors_t *mn, int i, int j, int k, double *h)
{
  double t1[8], t2[8], t3[8], s[16];
  const int n1 = i2m_ex_scale(mn->len[j][k], mn->m[j][k], p[i][2], t1);
  const int n2 = i2m_ex_scale(mn->len[i][k], mn->m[i][k], -p[j][2], t2);
  const int n3 = i2m_ex_scale(mn->len[i][j], mn->m[i][j], p[k][2], t3);
  const int ns = i2m_ex_sum(n1, t1, n2, t2, s);
  return i2m_ex_sum(ns, s, n3, t3, h);
}

/* O(q0,q1,q2,q3) = D(q1,q2,q3) - D(q0,q2,q3) + D(q0,q1,q3) - D(q0,q1,q2), q increasing;
 * h: 96 components. */
static int orient_exact(const double (*p)[3], const minors_t *mn, const int q[4], double *h)
{
  double d0[24], d1[24], d2[24], d3[24], s01[48], s23[48];
  const int n0 = det3_exact(p, mn, q[1], q[2], q[3], d0);
  const int n1 = det3_exact(p, mn, q[0], q[2], q[3], d1);
  const int n2 = det3_exact(p, mn, q[0], q[1], q[3], d2);
  const int n3 = det3_exact(p, mn, q[0], q[1], q[2], d3);
  const int m01 = i2m_ex_diff(n0, d0, n1, d1, s01);
  const int m23 = i2m_ex_diff(n2, d2, n3, d3, s23);
  return i2m_ex_sum(m01, s01, m23, s23, h);
}

/* Exact sign of O(p0,p1,p2,p3) for scaled (possibly translated) points. */
static int orient3d_exact_points(const double (*p)[3])
{
  minors_t mn;
  double o[96];
  static const int q[4] = {0, 1, 2, 3};
  minors_compute(4, p, &mn);
  return i2m_ex_sign(orient_exact(p, &mn, q, o), o);
}

/* w = x^2 + y^2 + z^2 exactly (<= 6 components), negated if neg. */
static int lift_exact(const double p[3], int neg, double *w)
{
  double e[3][2], s[4];
  int len[3];
  for (int k = 0; k < 3; k++) {
    double x, y;
    i2m_ex_two_square(p[k], &x, &y);
    len[k] = i2m_ex_from_pair(neg ? -y : y, neg ? -x : x, e[k]);
  }
  const int ns = i2m_ex_sum(len[0], e[0], len[1], e[1], s);
  return i2m_ex_sum(ns, s, len[2], e[2], w);
}

/* Exact sign of I(p0..p4) = sum_x s_x w_x O(others), s_x = +1 for odd x, -1 for even x.
 * Stack: two accumulators of 5 * 6 * 192 = 5760 components (the algorithmic bound), about
 * 95 KB. */
#define ISP_ACC_MAX 5760
static I2M_NOINLINE int insphere_exact_points(const double (*p)[3])
{
  minors_t mn;
  double acc[2][ISP_ACC_MAX], o[96], w[6], t[192];
  int alen = 0, cur = 0;
  minors_compute(5, p, &mn);
  for (int x = 0; x < 5; x++) {
    int q[4], nq = 0;
    for (int i = 0; i < 5; i++)
      if (i != x) q[nq++] = i;
    const int wlen = lift_exact(p[x], !(x & 1), w);
    if (wlen == 0) continue;
    const int olen = orient_exact(p, &mn, q, o);
    for (int j = 0; j < wlen; j++) {
      const int tlen = i2m_ex_scale(olen, o, w[j], t);
      alen = i2m_ex_sum(alen, acc[cur], tlen, t, acc[cur ^ 1]);
      cur ^= 1;
    }
  }
  return i2m_ex_sign(alen, acc[cur]);
}

/* The same determinants when the base point is the origin (exact differences): orient3d
 * reduces to D(u,v,w) and insphere to La D(b,c,d) - Lb D(a,c,d) + Lc D(a,b,d) - Ld D(a,b,c)
 * over the four other points (terms <= 6 x 24 x 2 = 288, sum <= 1152 components). */
static int orient3d_exact_translated(const double (*p)[3])
{
  minors_t mn;
  double d[24];
  minors_compute(4, p, &mn); /* the minors with p[0] = 0 are empty */
  return i2m_ex_sign(det3_exact(p, &mn, 1, 2, 3, d), d);
}

static I2M_NOINLINE int insphere_exact_translated(const double (*p)[3])
{
  minors_t mn;
  double acc[2][1152], d[24], w[6], t[48];
  int alen = 0, cur = 0;
  minors_compute(4, p, &mn);
  for (int x = 0; x < 4; x++) { /* term s_x Lx D(others among 0..3), s = (+, -, +, -) */
    int q[3], nq = 0;
    for (int i = 0; i < 4; i++)
      if (i != x) q[nq++] = i;
    const int wlen = lift_exact(p[x], x & 1, w);
    if (wlen == 0) continue;
    const int dlen = det3_exact(p, &mn, q[0], q[1], q[2], d);
    for (int j = 0; j < wlen; j++) {
      const int tlen = i2m_ex_scale(dlen, d, w[j], t);
      alen = i2m_ex_sum(alen, acc[cur], tlen, t, acc[cur ^ 1]);
      cur ^= 1;
    }
  }
  return i2m_ex_sign(alen, acc[cur]);
}

/* ---- orient3d ------------------------------------------------------------------------------ */

static I2M_COLD int orient3d_exact(const double a[3], const double b[3], const double c[3],
                                   const double d[3])
{
  const double *src[4] = {a, b, c, d};
  double p[4][3];
  if (!scale_points(4, src, 3, T_O3D, 1, p)) return 0;
  if (translate_if_exact(4, 0, p)) return orient3d_exact_translated((const double(*)[3])p);
  return orient3d_exact_points((const double(*)[3])p);
}

int i2m_orient3d(const double a[3], const double b[3], const double c[3], const double d[3])
{
  const int s = i2m_orient3d_filter(a, b, c, d);
  if (I2M_LIKELY(s != 0)) return s;
  return orient3d_exact(a, b, c, d);
}

double i2m_orient3d_fast(const double a[3], const double b[3], const double c[3], const double d[3])
{
  const double ux = b[0] - a[0], uy = b[1] - a[1], uz = b[2] - a[2];
  const double vx = c[0] - a[0], vy = c[1] - a[1], vz = c[2] - a[2];
  const double wx = d[0] - a[0], wy = d[1] - a[1], wz = d[2] - a[2];
  return uz * (vx * wy - wx * vy) - vz * (ux * wy - wx * uy) + wz * (ux * vy - vx * uy);
}

/* ---- insphere ------------------------------------------------------------------------------ */

static I2M_COLD int insphere_exact(const double a[3], const double b[3], const double c[3],
                                   const double d[3], const double e[3])
{
  const double *src[5] = {a, b, c, d, e};
  double p[5][3];
  if (!scale_points(5, src, 3, T_ISP, 0, p)) return 0;
  if (translate_if_exact(5, 4, p)) return insphere_exact_translated((const double(*)[3])p);
  return insphere_exact_points((const double(*)[3])p);
}

int i2m_insphere(const double a[3], const double b[3], const double c[3], const double d[3],
                 const double e[3])
{
  const int s = i2m_insphere_filter(a, b, c, d, e);
  if (I2M_LIKELY(s != 0)) return s;
  return insphere_exact(a, b, c, d, e);
}

/* Degenerate case of insphere_sos (exact insphere == 0).  With w_i -> w_i + eps_i the
 * perturbed I is affine in the eps_i: I + sum_i eps_i dI/dw_i, and by the expansion of I
 * above dI/dw_x = s_x O(others in their order a..e), s = (-, +, -, +, -).  eps of the
 * smallest id dominates, so the sign is that of the first non-zero cofactor by increasing
 * id.  All five cofactors vanish only when the five points are coplanar. */
static I2M_NOINLINE int insphere_sos_tiebreak(const double *const pts[5], const i2m_gidx_t ids[5])
{
  int order[5] = {0, 1, 2, 3, 4};
  for (int i = 1; i < 5; i++) /* insertion sort of the positions by id */
    for (int j = i; j > 0 && ids[order[j]] < ids[order[j - 1]]; j--) {
      const int t = order[j];
      order[j] = order[j - 1];
      order[j - 1] = t;
    }
  for (int k = 0; k < 5; k++) {
    const int x = order[k];
    const double *q[4];
    int nq = 0;
    for (int i = 0; i < 5; i++)
      if (i != x) q[nq++] = pts[i];
    const int o = i2m_orient3d(q[0], q[1], q[2], q[3]);
    if (o != 0) return (x & 1) ? o : -o;
  }
  return 0;
}

int i2m_insphere_sos_exact(const double a[3], const double b[3], const double c[3], const double d[3],
                           const double e[3], i2m_gidx_t ia, i2m_gidx_t ib, i2m_gidx_t ic, i2m_gidx_t id,
                           i2m_gidx_t ie)
{
  const int s = insphere_exact(a, b, c, d, e);
  if (s != 0) return s;
  const double *const pts[5] = {a, b, c, d, e};
  const i2m_gidx_t ids[5] = {ia, ib, ic, id, ie};
  return insphere_sos_tiebreak(pts, ids);
}

int i2m_insphere_sos(const double a[3], const double b[3], const double c[3], const double d[3],
                     const double e[3], i2m_gidx_t ia, i2m_gidx_t ib, i2m_gidx_t ic,
                     i2m_gidx_t id, i2m_gidx_t ie)
{
  const int s = i2m_insphere_filter(a, b, c, d, e);
  if (I2M_LIKELY(s != 0)) return s;
  return i2m_insphere_sos_exact(a, b, c, d, e, ia, ib, ic, id, ie);
}

double i2m_insphere_fast(const double a[3], const double b[3], const double c[3], const double d[3],
                         const double e[3])
{
  const double ax = a[0] - e[0], ay = a[1] - e[1], az = a[2] - e[2];
  const double bx = b[0] - e[0], by = b[1] - e[1], bz = b[2] - e[2];
  const double cx = c[0] - e[0], cy = c[1] - e[1], cz = c[2] - e[2];
  const double dx = d[0] - e[0], dy = d[1] - e[1], dz = d[2] - e[2];
  const double mab = ax * by - bx * ay, mac = ax * cy - cx * ay, mad = ax * dy - dx * ay;
  const double mbc = bx * cy - cx * by, mbd = bx * dy - dx * by, mcd = cx * dy - dx * cy;
  const double dbcd = bz * mcd - cz * mbd + dz * mbc;
  const double dacd = az * mcd - cz * mad + dz * mac;
  const double dabd = az * mbd - bz * mad + dz * mab;
  const double dabc = az * mbc - bz * mac + cz * mab;
  const double la = ax * ax + ay * ay + az * az;
  const double lb = bx * bx + by * by + bz * bz;
  const double lc = cx * cx + cy * cy + cz * cz;
  const double ld = dx * dx + dy * dy + dz * dz;
  return (la * dbcd - lb * dacd) + (lc * dabd - ld * dabc);
}

/* ---- orient2d on a coordinate plane ------------------------------------------------------- */

static I2M_COLD int orient2d_proj_exact(const double a[3], const double b[3], const double c[3],
                                        int i, int j)
{
  /* the two kept coordinates become x, y of 3D points with z = 0 */
  const double pa[3] = {a[i], a[j], 0.0}, pb[3] = {b[i], b[j], 0.0}, pc[3] = {c[i], c[j], 0.0};
  const double *src[3] = {pa, pb, pc};
  double p[3][3];
  if (!scale_points(3, src, 2, T_O2D, 1, p)) return 0;
  (void)translate_if_exact(3, 0, p);
  /* m(a,b) + m(b,c) + m(c,a) = (bx-ax)(cy-ay) - (by-ay)(cx-ax) */
  double m1[4], m2[4], m3[4], s[8], h[12];
  const int n1 = i2m_ex_two_products_diff(p[0][0], p[1][1], p[1][0], p[0][1], m1);
  const int n2 = i2m_ex_two_products_diff(p[1][0], p[2][1], p[2][0], p[1][1], m2);
  const int n3 = i2m_ex_two_products_diff(p[2][0], p[0][1], p[0][0], p[2][1], m3);
  const int ns = i2m_ex_sum(n1, m1, n2, m2, s);
  return i2m_ex_sign(i2m_ex_sum(ns, s, n3, m3, h), h);
}

int i2m_orient2d_proj(const double a[3], const double b[3], const double c[3], int drop)
{
  I2M_ASSERT(drop >= 0 && drop <= 2);
  const int i = drop == 0 ? 1 : 0, j = drop == 2 ? 1 : 2;
  const double ux = b[i] - a[i], uy = b[j] - a[j];
  const double vx = c[i] - a[i], vy = c[j] - a[j];
  const double l = ux * vy, r = uy * vx;
  const double det = l - r;
  const double perm = fabs(l) + fabs(r);
  const double bound = O2D_BOUND * perm;
  if (I2M_LIKELY((fabs(det) > bound) & (perm >= O2D_PERM_MIN))) return (det > 0.0) - (det < 0.0);
  return orient2d_proj_exact(a, b, c, i, j);
}
