/* Unit tests of the robust predicates (geometry layer 1).  Every sign is compared with a
 * reference computed by exact rational arithmetic implemented independently here (not with
 * the expansion code): a double is a dyadic rational m 2^e, so the coordinates of a query
 * are brought to a common power of two and the determinants are evaluated with a small
 * signed big-integer type (32-bit limbs).  Scaling a column by a positive factor keeps the
 * sign of a determinant, so integer coordinates X = x 2^-E and integer lifts X^2+Y^2+Z^2
 * give the signs of the real determinants.
 *
 * References (rows are the points, in argument order):
 *   orient3d(a,b,c,d)  = det [b-a; c-a; d-a]                       (header definition)
 *   insphere(a..e)     = -det [x y z w 1],  w = x^2 + y^2 + z^2    (5x5, Laplace expansion)
 *     The factor -1 is anchored by test_conventions: for fixed a,b,c,d the 5x5 determinant
 *     is an affine function of (e, |e|^2) whose |e|^2 coefficient is +-orient3d(a,b,c,d),
 *     so one interior point of one positive tet fixes the sign for every positive tet, and
 *     the flip for negative tets is automatic.
 *   insphere_sos: w_i -> w_i + eps_i, eps_i = eps^(2^rank(id_i)).  The 5x5 determinant is
 *     linear in the w column, so the perturbed value is -det[x y z w 1] + sum_i eps_i
 *     (-det[x y z e_i 1]) with e_i the i-th unit vector: the coefficient of eps_i is, by
 *     definition, the 5x5 determinant with the w column replaced by e_i.  The reference
 *     sign is that of det if non-zero, else of the first non-zero coefficient by increasing
 *     id (the smallest id has the largest eps_i). */
#include "i2m/predicates.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_util.h"

/* ---- signed big integers ------------------------------------------------------------------ */

#define BN_LIMBS 96 /* 3072 bits: degree-5 products of coordinates spanning ~600 bits */
typedef struct {
  int neg;            /* 1 if negative (never for zero) */
  int n;              /* limbs in use, no leading zero limb; 0 for zero */
  uint32_t d[BN_LIMBS]; /* magnitude, little-endian */
} bn_t;

static void bn_overflow(void)
{
  fprintf(stderr, "test_geom_predicates: big integer capacity exceeded\n");
  abort();
}

static void bn_zero(bn_t *r) { r->neg = 0; r->n = 0; }
static int bn_sign(const bn_t *a) { return a->n == 0 ? 0 : (a->neg ? -1 : 1); }
static void bn_trim(bn_t *r)
{
  while (r->n > 0 && r->d[r->n - 1] == 0) r->n--;
  if (r->n == 0) r->neg = 0;
}

static int mag_cmp(const bn_t *a, const bn_t *b)
{
  if (a->n != b->n) return a->n < b->n ? -1 : 1;
  for (int i = a->n - 1; i >= 0; i--)
    if (a->d[i] != b->d[i]) return a->d[i] < b->d[i] ? -1 : 1;
  return 0;
}

/* r = |a| + |b| (sign left to the caller) */
static void mag_add(bn_t *r, const bn_t *a, const bn_t *b)
{
  bn_t t;
  int n = a->n > b->n ? a->n : b->n;
  uint64_t carry = 0;
  for (int i = 0; i < n; i++) {
    uint64_t s = carry + (i < a->n ? a->d[i] : 0) + (i < b->n ? b->d[i] : 0);
    t.d[i] = (uint32_t)s;
    carry = s >> 32;
  }
  if (carry) {
    if (n >= BN_LIMBS) bn_overflow();
    t.d[n++] = (uint32_t)carry;
  }
  t.n = n;
  t.neg = 0;
  *r = t;
}

/* r = |a| - |b|, requires |a| >= |b| */
static void mag_sub(bn_t *r, const bn_t *a, const bn_t *b)
{
  bn_t t;
  int64_t borrow = 0;
  for (int i = 0; i < a->n; i++) {
    int64_t s = (int64_t)a->d[i] - (i < b->n ? b->d[i] : 0) - borrow;
    borrow = s < 0;
    t.d[i] = (uint32_t)(s + (borrow ? ((int64_t)1 << 32) : 0));
  }
  t.n = a->n;
  t.neg = 0;
  bn_trim(&t);
  *r = t;
}

/* r = a + (negb ? -b : b) */
static void bn_addsub(bn_t *r, const bn_t *a, const bn_t *b, int negb)
{
  const int bneg = b->n ? (b->neg ^ negb) : 0;
  if (a->neg == bneg) {
    const int s = a->neg;
    mag_add(r, a, b);
    r->neg = r->n ? s : 0;
  } else if (mag_cmp(a, b) >= 0) {
    const int s = a->neg;
    mag_sub(r, a, b);
    r->neg = r->n ? s : 0;
  } else {
    mag_sub(r, b, a);
    r->neg = r->n ? bneg : 0;
  }
}
static void bn_add(bn_t *r, const bn_t *a, const bn_t *b) { bn_addsub(r, a, b, 0); }
static void bn_sub(bn_t *r, const bn_t *a, const bn_t *b) { bn_addsub(r, a, b, 1); }

static void bn_mul(bn_t *r, const bn_t *a, const bn_t *b)
{
  bn_t t;
  if (a->n == 0 || b->n == 0) {
    bn_zero(r);
    return;
  }
  const int n = a->n + b->n;
  if (n > BN_LIMBS) bn_overflow();
  memset(t.d, 0, sizeof(uint32_t) * (size_t)n);
  for (int i = 0; i < a->n; i++) {
    uint64_t carry = 0;
    for (int j = 0; j < b->n; j++) {
      uint64_t s = (uint64_t)a->d[i] * b->d[j] + t.d[i + j] + carry;
      t.d[i + j] = (uint32_t)s;
      carry = s >> 32;
    }
    t.d[i + b->n] = (uint32_t)carry;
  }
  t.n = n;
  t.neg = a->neg ^ b->neg;
  bn_trim(&t);
  *r = t;
}

/* r = m * 2^shift, |m| < 2^63, shift >= 0 */
static void bn_from_shifted(bn_t *r, int64_t m, int shift)
{
  bn_zero(r);
  if (m == 0) return;
  uint64_t u = m < 0 ? (uint64_t)(-m) : (uint64_t)m;
  const int limb = shift / 32, bit = shift % 32;
  if (limb + 4 > BN_LIMBS) bn_overflow();
  memset(r->d, 0, sizeof(uint32_t) * (size_t)(limb + 4));
  /* u << bit fits in 96 bits */
  const uint64_t lo = (u << bit) & 0xffffffffffffffffULL;
  const uint64_t hi = bit ? (u >> (64 - bit)) : 0;
  r->d[limb] = (uint32_t)lo;
  r->d[limb + 1] = (uint32_t)(lo >> 32);
  r->d[limb + 2] = (uint32_t)hi;
  r->n = limb + 3;
  r->neg = m < 0;
  bn_trim(r);
}

/* ---- doubles as integers at a common exponent --------------------------------------------- */

/* x = m 2^e with |m| < 2^53 (frexp is exact, subnormals included) */
static void dyadic(double x, int64_t *m, int *e)
{
  int ex = 0;
  const double f = frexp(x, &ex);
  *m = (int64_t)ldexp(f, 53);
  *e = ex - 53;
}

/* X[i][k] = pts[i][k] * 2^-E for the smallest exponent E of the query */
static void exact_coords(int n, const double *const *pts, bn_t (*X)[3])
{
  int64_t m[5][3];
  int e[5][3], emin = 1 << 30;
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) {
      dyadic(pts[i][k], &m[i][k], &e[i][k]);
      if (m[i][k] != 0 && e[i][k] < emin) emin = e[i][k];
    }
  for (int i = 0; i < n; i++)
    for (int k = 0; k < 3; k++) bn_from_shifted(&X[i][k], m[i][k], m[i][k] ? e[i][k] - emin : 0);
}

/* ---- exact determinants ------------------------------------------------------------------ */

/* det of the submatrix of M on rows[0..n-1] x cols[0..n-1], Laplace expansion along the
 * column with the most zeros */
static void bn_det(const bn_t (*M)[5], int n, const int *rows, const int *cols, bn_t *out)
{
  if (n == 1) {
    *out = M[rows[0]][cols[0]];
    return;
  }
  int best = 0, bestz = -1;
  for (int j = 0; j < n; j++) {
    int z = 0;
    for (int i = 0; i < n; i++) z += M[rows[i]][cols[j]].n == 0;
    if (z > bestz) { bestz = z; best = j; }
  }
  int subc[5], nc = 0;
  for (int j = 0; j < n; j++)
    if (j != best) subc[nc++] = cols[j];
  bn_t acc, minor, prod;
  bn_zero(&acc);
  for (int i = 0; i < n; i++) {
    const bn_t *ent = &M[rows[i]][cols[best]];
    if (ent->n == 0) continue;
    int subr[5], nr = 0;
    for (int r = 0; r < n; r++)
      if (r != i) subr[nr++] = rows[r];
    bn_det(M, n - 1, subr, subc, &minor);
    bn_mul(&prod, ent, &minor);
    if ((i + best) & 1) bn_sub(&acc, &acc, &prod);
    else bn_add(&acc, &acc, &prod);
  }
  *out = acc;
}

static int ref_orient3d(const double *a, const double *b, const double *c, const double *d)
{
  const double *pts[4] = {a, b, c, d};
  bn_t X[4][3], M[5][5];
  exact_coords(4, pts, X);
  for (int i = 0; i < 3; i++)
    for (int k = 0; k < 3; k++) bn_sub(&M[i][k], &X[i + 1][k], &X[0][k]);
  static const int idx[3] = {0, 1, 2};
  bn_t det;
  bn_det((const bn_t(*)[5])M, 3, idx, idx, &det);
  return bn_sign(&det);
}

/* -det [x y z w 1] with the w column replaced by e_unit when unit >= 0 */
static int ref_insphere_col(const double *const pts[5], int unit)
{
  bn_t X[5][3], M[5][5], t;
  exact_coords(5, pts, X);
  for (int i = 0; i < 5; i++) {
    for (int k = 0; k < 3; k++) M[i][k] = X[i][k];
    if (unit < 0) {
      bn_mul(&M[i][3], &X[i][0], &X[i][0]);
      bn_mul(&t, &X[i][1], &X[i][1]);
      bn_add(&M[i][3], &M[i][3], &t);
      bn_mul(&t, &X[i][2], &X[i][2]);
      bn_add(&M[i][3], &M[i][3], &t);
    } else {
      bn_from_shifted(&M[i][3], i == unit, 0);
    }
    bn_from_shifted(&M[i][4], 1, 0);
  }
  static const int idx[5] = {0, 1, 2, 3, 4};
  bn_t det;
  bn_det((const bn_t(*)[5])M, 5, idx, idx, &det);
  return -bn_sign(&det);
}

static int ref_insphere(const double *const pts[5]) { return ref_insphere_col(pts, -1); }

static int ref_insphere_sos(const double *const pts[5], const i2m_gidx_t ids[5])
{
  const int s = ref_insphere_col(pts, -1);
  if (s) return s;
  int used[5] = {0, 0, 0, 0, 0};
  for (int k = 0; k < 5; k++) {
    int m = -1;
    for (int i = 0; i < 5; i++)
      if (!used[i] && (m < 0 || ids[i] < ids[m])) m = i;
    used[m] = 1;
    const int c = ref_insphere_col(pts, m);
    if (c) return c;
  }
  return 0;
}

static int ref_orient2d_proj(const double *a, const double *b, const double *c, int drop)
{
  const double *pts[3] = {a, b, c};
  bn_t X[3][3], M[5][5];
  exact_coords(3, pts, X);
  const int i0 = drop == 0 ? 1 : 0, i1 = drop == 2 ? 1 : 2;
  for (int r = 0; r < 2; r++) {
    bn_sub(&M[r][0], &X[r + 1][i0], &X[0][i0]);
    bn_sub(&M[r][1], &X[r + 1][i1], &X[0][i1]);
  }
  static const int idx[2] = {0, 1};
  bn_t det;
  bn_det((const bn_t(*)[5])M, 2, idx, idx, &det);
  return bn_sign(&det);
}

/* ---- random numbers (splitmix64, fixed seeds) --------------------------------------------- */

typedef struct {
  uint64_t s;
} rng_t;
static uint64_t rng_next(rng_t *r)
{
  uint64_t z = (r->s += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}
static double rng_unit(rng_t *r) { return (double)(rng_next(r) >> 11) * 0x1p-53; }
static int rng_int(rng_t *r, int lo, int hi) { return lo + (int)(rng_next(r) % (uint64_t)(hi - lo + 1)); }
static double rng_sym(rng_t *r) { return 2.0 * rng_unit(r) - 1.0; }

/* ---- the comparison harness ---------------------------------------------------------------- */

typedef struct {
  long queries, wrong, zeros_o3, zeros_isp, zeros_sos, fast_wrong;
} stats_t;

static void report_wrong(const char *what, const double *const p[5], int got, int want)
{
  fprintf(stderr, "  %s: got %d want %d for", what, got, want);
  for (int i = 0; i < 5; i++) fprintf(stderr, " (%a,%a,%a)", p[i][0], p[i][1], p[i][2]);
  fprintf(stderr, "\n");
}

static i2m_gidx_t random_ids(rng_t *r, i2m_gidx_t ids[5])
{
  for (int i = 0; i < 5; i++) {
    int again;
    do {
      ids[i] = (i2m_gidx_t)(rng_next(r) % 1000000007ULL);
      again = 0;
      for (int j = 0; j < i; j++) again |= ids[j] == ids[i];
    } while (again);
  }
  return ids[0];
}

static int sgn(double x) { return (x > 0) - (x < 0); }

/* Compares every predicate on the five points p (orient3d on the first four) with the
 * references. */
static void check_query(const double *const p[5], const i2m_gidx_t ids[5], int with_2d, stats_t *st)
{
  st->queries++;
  const int o = i2m_orient3d(p[0], p[1], p[2], p[3]), ro = ref_orient3d(p[0], p[1], p[2], p[3]);
  if (o != ro) {
    if (st->wrong++ < 5) report_wrong("orient3d", p, o, ro);
  }
  st->zeros_o3 += ro == 0;
  if (sgn(i2m_orient3d_fast(p[0], p[1], p[2], p[3])) != ro) st->fast_wrong++;
  const int s = i2m_insphere(p[0], p[1], p[2], p[3], p[4]), rs = ref_insphere(p);
  if (s != rs) {
    if (st->wrong++ < 5) report_wrong("insphere", p, s, rs);
  }
  st->zeros_isp += rs == 0;
  if (sgn(i2m_insphere_fast(p[0], p[1], p[2], p[3], p[4])) != rs) st->fast_wrong++;
  const int ss = i2m_insphere_sos(p[0], p[1], p[2], p[3], p[4], ids[0], ids[1], ids[2], ids[3], ids[4]);
  const int rss = rs ? rs : ref_insphere_sos(p, ids);
  if (ss != rss) {
    if (st->wrong++ < 5) report_wrong("insphere_sos", p, ss, rss);
  }
  st->zeros_sos += rss == 0;
  if (with_2d) {
    for (int drop = 0; drop < 3; drop++) {
      const int t = i2m_orient2d_proj(p[0], p[1], p[2], drop);
      const int rt = ref_orient2d_proj(p[0], p[1], p[2], drop);
      if (t != rt) {
        if (st->wrong++ < 5) report_wrong("orient2d_proj", p, t, rt);
      }
    }
  }
}

static void print_stats(const char *name, const stats_t *st)
{
  printf("\n    %s: %ld queries, %ld wrong, zeros: orient3d %ld insphere %ld sos %ld; "
         "naive double signs wrong: %ld\n",
         name, st->queries, st->wrong, st->zeros_o3, st->zeros_isp, st->zeros_sos, st->fast_wrong);
}

/* ---- point-set generators ------------------------------------------------------------------ */

typedef struct {
  double p[5][3];
  const double *ptr[5];
} pset_t;

static void pset_ptrs(pset_t *s)
{
  for (int i = 0; i < 5; i++) s->ptr[i] = s->p[i];
}

static void scale_pset(pset_t *s, int k)
{
  for (int i = 0; i < 5; i++)
    for (int c = 0; c < 3; c++) s->p[i][c] = ldexp(s->p[i][c], k);
}

/* small lattice: many coplanar, cospherical and coincident configurations */
static void gen_lattice(rng_t *r, pset_t *s, int n)
{
  for (int i = 0; i < 5; i++)
    for (int c = 0; c < 3; c++) s->p[i][c] = rng_int(r, 0, n);
}

/* integer grid, each coordinate perturbed by ~1e-12 with probability 1/2 */
static void gen_perturbed_grid(rng_t *r, pset_t *s)
{
  for (int i = 0; i < 5; i++)
    for (int c = 0; c < 3; c++)
      s->p[i][c] = rng_int(r, 0, 3) + ((rng_next(r) & 1) ? 1e-12 * rng_sym(r) : 0.0);
}

/* five distinct lattice points on a sphere x^2+y^2+z^2 = R (Pythagorean quadruples),
 * translated by an integer centre */
#define NSPHERES 6
static int sphere_pts[NSPHERES][2048][3], sphere_n[NSPHERES], sphere_done;
static void sphere_enumerate(void)
{
  static const int radii2[NSPHERES] = {9, 50, 81, 121, 243, 675};
  for (int k = 0; k < NSPHERES; k++) {
    const int R = radii2[k], rmax = (int)ceil(sqrt((double)R));
    sphere_n[k] = 0;
    for (int x = -rmax; x <= rmax; x++)
      for (int y = -rmax; y <= rmax; y++)
        for (int z = -rmax; z <= rmax; z++)
          if (x * x + y * y + z * z == R && sphere_n[k] < 2048) {
            sphere_pts[k][sphere_n[k]][0] = x;
            sphere_pts[k][sphere_n[k]][1] = y;
            sphere_pts[k][sphere_n[k]][2] = z;
            sphere_n[k]++;
          }
  }
  sphere_done = 1;
}
static void gen_cospherical(rng_t *r, pset_t *s)
{
  if (!sphere_done) sphere_enumerate();
  const int k = rng_int(r, 0, NSPHERES - 1), sphere_npts = sphere_n[k];
  int(*sphere)[3] = sphere_pts[k];
  int pick[5];
  for (int i = 0; i < 5; i++) {
    int again;
    do {
      pick[i] = rng_int(r, 0, sphere_npts - 1);
      again = 0;
      for (int j = 0; j < i; j++) again |= pick[j] == pick[i];
    } while (again);
  }
  const int cx = rng_int(r, -1000, 1000), cy = rng_int(r, -1000, 1000), cz = rng_int(r, -1000, 1000);
  for (int i = 0; i < 5; i++) {
    s->p[i][0] = cx + sphere[pick[i]][0];
    s->p[i][1] = cy + sphere[pick[i]][1];
    s->p[i][2] = cz + sphere[pick[i]][2];
  }
}

/* five points exactly on the plane z = (x + 3y)/4 + 5 (dyadic x, y with few bits), then
 * with probability 1/2 one coordinate multiplied by (1 +- 2^-50) */
static void gen_plane(rng_t *r, pset_t *s)
{
  for (int i = 0; i < 5; i++) {
    const double x = ldexp((double)rng_int(r, -100000, 100000), -10);
    const double y = ldexp((double)rng_int(r, -100000, 100000), -10);
    s->p[i][0] = x;
    s->p[i][1] = y;
    s->p[i][2] = (x + 3.0 * y) / 4.0 + 5.0;
  }
  if (rng_next(r) & 1) {
    const int i = rng_int(r, 0, 4), c = rng_int(r, 0, 2);
    s->p[i][c] *= 1.0 + ((rng_next(r) & 1) ? 0x1p-50 : -0x1p-50);
  }
}

/* one non-zero coordinate of one point moved by one ulp (nextafter), up or down (moving a
 * zero would create a subnormal next to coordinates ~1e3, outside the documented range) */
static void ulp_move(rng_t *r, pset_t *s)
{
  for (int tries = 0; tries < 100; tries++) {
    const int i = rng_int(r, 0, 4), c = rng_int(r, 0, 2);
    if (s->p[i][c] == 0.0) continue;
    s->p[i][c] = nextafter(s->p[i][c], (rng_next(r) & 1) ? HUGE_VAL : -HUGE_VAL);
    return;
  }
}

/* a degenerate or nearly degenerate set of one of the kinds above */
static void gen_any(rng_t *r, pset_t *s)
{
  switch (rng_int(r, 0, 4)) {
  case 0: gen_lattice(r, s, 2); break;
  case 1: gen_perturbed_grid(r, s); break;
  case 2: gen_cospherical(r, s); break;
  case 3: gen_plane(r, s); break;
  default:
    if (rng_next(r) & 1) gen_cospherical(r, s);
    else gen_plane(r, s);
    ulp_move(r, s);
    break;
  }
  pset_ptrs(s);
}

/* ---- tests ----------------------------------------------------------------------------------- */

static void test_conventions(void)
{
  const double o[3] = {0, 0, 0}, x[3] = {1, 0, 0}, y[3] = {0, 1, 0}, z[3] = {0, 0, 1};
  const double in[3] = {0.25, 0.25, 0.25}, on[3] = {1, 1, 1}, out[3] = {2, 2, 2};
  const double cc[3] = {0.5, 0.5, 0.5};
  CU_ASSERT_EQUAL(i2m_orient3d(o, x, y, z), 1);
  CU_ASSERT_EQUAL(i2m_orient3d(o, y, x, z), -1);
  CU_ASSERT_EQUAL(i2m_orient3d(o, x, y, in), 1);
  CU_ASSERT_EQUAL(i2m_orient3d(o, x, y, o), 0);
  CU_ASSERT(i2m_orient3d_fast(o, x, y, z) == 1.0);
  /* the reference's insphere sign is anchored here on the header's geometric definition */
  const double *pin[5] = {o, x, y, z, in}, *pcc[5] = {o, x, y, z, cc};
  CU_ASSERT_EQUAL(ref_insphere(pin), 1);
  CU_ASSERT_EQUAL(ref_insphere(pcc), 1);
  CU_ASSERT_EQUAL(ref_orient3d(o, x, y, z), 1);
  CU_ASSERT_EQUAL(i2m_insphere(o, x, y, z, in), 1);
  CU_ASSERT_EQUAL(i2m_insphere(o, x, y, z, cc), 1);
  CU_ASSERT_EQUAL(i2m_insphere(o, x, y, z, on), 0); /* (1,1,1) is on the circumsphere */
  CU_ASSERT_EQUAL(i2m_insphere(o, x, y, z, out), -1);
  CU_ASSERT_EQUAL(i2m_insphere(o, y, x, z, cc), -1); /* negative tet: the sign flips */
  CU_ASSERT_EQUAL(i2m_insphere(o, y, x, z, out), 1);
  CU_ASSERT(i2m_insphere_fast(o, x, y, z, cc) > 0.0);
  CU_ASSERT(i2m_insphere_fast(o, x, y, z, out) < 0.0);
  /* a vertex of the tet is on its own sphere */
  CU_ASSERT_EQUAL(i2m_insphere(o, x, y, z, x), 0);
  /* SoS: (1,1,1) with the smallest id: the perturbation lifts it outside */
  CU_ASSERT_EQUAL(i2m_insphere_sos(o, x, y, z, on, 2, 3, 4, 5, 1), -1);
  /* a smallest: coefficient -orient3d(x,y,z,on) = -2; b smallest: +orient3d(o,y,z,on) = 1 */
  CU_ASSERT_EQUAL(i2m_insphere_sos(o, x, y, z, on, 1, 2, 3, 4, 5), -1);
  CU_ASSERT_EQUAL(i2m_insphere_sos(o, x, y, z, on, 2, 1, 3, 4, 5), 1);
  /* five coplanar points: 0 */
  const double q[3] = {0.5, 0.25, 0};
  CU_ASSERT_EQUAL(i2m_insphere_sos(o, x, y, q, cc, 1, 2, 3, 4, 5) != 0, 1);
  const double q2[3] = {3, 7, 0}, q3[3] = {-2, 5, 0};
  CU_ASSERT_EQUAL(i2m_insphere_sos(o, x, y, q2, q3, 1, 2, 3, 4, 5), 0);
  /* orient2d_proj: (x,y) for drop 2, (y,z) for drop 0, (x,z) for drop 1 */
  CU_ASSERT_EQUAL(i2m_orient2d_proj(o, x, y, 2), 1);
  CU_ASSERT_EQUAL(i2m_orient2d_proj(o, y, x, 2), -1);
  CU_ASSERT_EQUAL(i2m_orient2d_proj(o, y, z, 0), 1);
  CU_ASSERT_EQUAL(i2m_orient2d_proj(o, x, z, 1), 1);
  CU_ASSERT_EQUAL(i2m_orient2d_proj(o, x, y, 0), 0);
  CU_ASSERT_EQUAL(ref_orient2d_proj(o, x, z, 1), 1);
  /* non-finite and all-zero input */
  const double nan3[3] = {NAN, 0, 0};
  CU_ASSERT_EQUAL(i2m_orient3d(o, x, y, nan3), 0);
  CU_ASSERT_EQUAL(i2m_insphere(o, o, o, o, o), 0);
  CU_ASSERT_EQUAL(i2m_orient3d(o, o, o, o), 0);
}

/* a family of queries from a generator, compared with the references */
static void run_family(const char *name, uint64_t seed, int n, int scale_lo, int scale_hi,
                       stats_t *st)
{
  rng_t r = {seed};
  pset_t s;
  i2m_gidx_t ids[5];
  for (int q = 0; q < n; q++) {
    gen_any(&r, &s);
    if (scale_lo != 0 || scale_hi != 0) scale_pset(&s, rng_int(&r, scale_lo, scale_hi));
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, st);
  }
  print_stats(name, st);
}

static void test_perturbed_grid(void)
{
  rng_t r = {1};
  pset_t s;
  stats_t st = {0};
  i2m_gidx_t ids[5];
  for (int q = 0; q < 4000; q++) {
    gen_perturbed_grid(&r, &s);
    pset_ptrs(&s);
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, &st);
  }
  print_stats("perturbed grid", &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
  CU_ASSERT(st.zeros_o3 > 10 && st.zeros_isp > 5);
}

static void test_lattice(void)
{
  rng_t r = {2};
  pset_t s;
  stats_t st = {0};
  i2m_gidx_t ids[5];
  for (int q = 0; q < 4000; q++) {
    gen_lattice(&r, &s, q & 1 ? 2 : 4);
    const double off[3] = {rng_int(&r, -1000, 1000), rng_int(&r, -1000, 1000), rng_int(&r, -1000, 1000)};
    for (int i = 0; i < 5; i++)
      for (int c = 0; c < 3; c++) s.p[i][c] += off[c];
    scale_pset(&s, rng_int(&r, -30, 30));
    pset_ptrs(&s);
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, &st);
  }
  print_stats("lattice", &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
  CU_ASSERT(st.zeros_o3 > 500 && st.zeros_isp > 500 && st.zeros_sos > 50);
}

static void test_cospherical(void)
{
  rng_t r = {3};
  pset_t s;
  stats_t st = {0};
  i2m_gidx_t ids[5];
  long nonzero = 0;
  for (int q = 0; q < 3000; q++) {
    gen_cospherical(&r, &s);
    scale_pset(&s, rng_int(&r, -20, 20));
    pset_ptrs(&s);
    random_ids(&r, ids);
    nonzero += i2m_insphere(s.ptr[0], s.ptr[1], s.ptr[2], s.ptr[3], s.ptr[4]) != 0;
    check_query(s.ptr, ids, 0, &st);
  }
  print_stats("cospherical (Pythagorean quadruples)", &st);
  CU_ASSERT_EQUAL(nonzero, 0);
  CU_ASSERT_EQUAL(st.wrong, 0);
  CU_ASSERT_EQUAL(st.zeros_isp, st.queries);
}

static void test_plane(void)
{
  rng_t r = {4};
  pset_t s;
  stats_t st = {0};
  i2m_gidx_t ids[5];
  for (int q = 0; q < 3000; q++) {
    gen_plane(&r, &s);
    pset_ptrs(&s);
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, &st);
  }
  print_stats("plane with 2^-50 perturbations", &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
  CU_ASSERT(st.zeros_o3 > 500 && st.zeros_sos > 500);
}

static void test_ulp_off(void)
{
  rng_t r = {5};
  pset_t s;
  stats_t st = {0};
  i2m_gidx_t ids[5];
  for (int q = 0; q < 3000; q++) {
    if (q & 1) gen_cospherical(&r, &s);
    else gen_plane(&r, &s);
    ulp_move(&r, &s);
    pset_ptrs(&s);
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, &st);
  }
  print_stats("one ulp off a plane / sphere", &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
}

static void test_huge(void)
{
  stats_t st = {0};
  run_family("huge (2^332..2^500, 1e100..3e150)", 6, 3000, 332, 500, &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
  stats_t st2 = {0};
  run_family("near DBL_MAX (2^980..2^1000)", 7, 1000, 980, 1000, &st2);
  CU_ASSERT_EQUAL(st2.wrong, 0);
  /* generic huge coordinates with independent magnitudes 1e100..1e150 */
  rng_t r = {8};
  pset_t s;
  stats_t st3 = {0};
  i2m_gidx_t ids[5];
  for (int q = 0; q < 1000; q++) {
    for (int i = 0; i < 5; i++)
      for (int c = 0; c < 3; c++) s.p[i][c] = rng_sym(&r) * pow(10.0, 100.0 + 50.0 * rng_unit(&r));
    if (q & 1) ulp_move(&r, &s);
    pset_ptrs(&s);
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, &st3);
  }
  print_stats("random 1e100..1e150", &st3);
  CU_ASSERT_EQUAL(st3.wrong, 0);
}

static void test_tiny(void)
{
  stats_t st = {0};
  run_family("tiny (2^-340..2^-330, ~1e-100)", 9, 3000, -340, -330, &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
  stats_t st2 = {0};
  run_family("subnormal range (2^-1060..2^-1040)", 10, 1000, -1060, -1040, &st2);
  CU_ASSERT_EQUAL(st2.wrong, 0);
}

/* Mixed scales inside one query, within the documented exact range: per-point and per-axis
 * factors.  Axis scaling keeps coplanarity exact, so degenerate orient3d cases remain. */
static void test_mixed_scales(void)
{
  rng_t r = {11};
  pset_t s;
  stats_t st = {0}, st3 = {0};
  i2m_gidx_t ids[5];
  for (int q = 0; q < 3000; q++) {
    gen_any(&r, &s);
    if (q & 1) { /* per point */
      for (int i = 0; i < 5; i++) {
        const int k = rng_int(&r, -150, 150);
        for (int c = 0; c < 3; c++) s.p[i][c] = ldexp(s.p[i][c], k);
      }
    } else { /* per axis */
      for (int c = 0; c < 3; c++) {
        const int k = rng_int(&r, -150, 150);
        for (int i = 0; i < 5; i++) s.p[i][c] = ldexp(s.p[i][c], k);
      }
    }
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, &st);
  }
  /* the extreme of the documented insphere range: x axis scaled by 2^170, y and z by
   * 2^-170 (ratio 2^350 with the data) */
  for (int q = 0; q < 2000; q++) {
    gen_any(&r, &s);
    const int kx = (q & 1) ? 170 : -170;
    for (int i = 0; i < 5; i++) {
      s.p[i][0] = ldexp(s.p[i][0], kx);
      s.p[i][1] = ldexp(s.p[i][1], -kx);
      s.p[i][2] = ldexp(s.p[i][2], (q & 2) ? kx : -kx);
    }
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, &st);
  }
  print_stats("mixed scales 2^-150..2^150 per point / per axis, and 2^+-170 axes", &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
  /* orient3d and orient2d with a wider spread (documented 2^630 for orient3d) */
  for (int q = 0; q < 3000; q++) {
    gen_any(&r, &s);
    for (int c = 0; c < 3; c++) {
      const int k = rng_int(&r, -280, 280);
      for (int i = 0; i < 5; i++) s.p[i][c] = ldexp(s.p[i][c], k);
    }
    if (q & 1) ulp_move(&r, &s);
    st3.queries++;
    const int o = i2m_orient3d(s.ptr[0], s.ptr[1], s.ptr[2], s.ptr[3]);
    const int ro = ref_orient3d(s.ptr[0], s.ptr[1], s.ptr[2], s.ptr[3]);
    st3.zeros_o3 += ro == 0;
    if (o != ro && st3.wrong++ < 5) report_wrong("orient3d", s.ptr, o, ro);
    for (int drop = 0; drop < 3; drop++) {
      const int t = i2m_orient2d_proj(s.ptr[0], s.ptr[1], s.ptr[2], drop);
      const int rt = ref_orient2d_proj(s.ptr[0], s.ptr[1], s.ptr[2], drop);
      if (t != rt && st3.wrong++ < 5) report_wrong("orient2d_proj", s.ptr, t, rt);
    }
  }
  print_stats("orient3d/2d, axis scales 2^-280..2^280", &st3);
  CU_ASSERT_EQUAL(st3.wrong, 0);
  CU_ASSERT(st3.zeros_o3 > 300);
}

/* parity of a permutation of 0..n-1 */
static int perm_parity(const int *p, int n)
{
  int par = 0;
  for (int i = 0; i < n; i++)
    for (int j = i + 1; j < n; j++) par ^= p[i] > p[j];
  return par ? -1 : 1;
}

/* next permutation in lexicographic order; 0 when done */
static int next_perm(int *p, int n)
{
  int i = n - 2;
  while (i >= 0 && p[i] > p[i + 1]) i--;
  if (i < 0) return 0;
  int j = n - 1;
  while (p[j] < p[i]) j--;
  int t = p[i]; p[i] = p[j]; p[j] = t;
  for (int a = i + 1, b = n - 1; a < b; a++, b--) { t = p[a]; p[a] = p[b]; p[b] = t; }
  return 1;
}

static void test_permutations(void)
{
  rng_t r = {12};
  pset_t s;
  long bad_o3 = 0, bad_isp = 0, bad_sos = 0, bad_relabel = 0, sos_nonzero = 0, flips = 0;
  i2m_gidx_t ids[5];
  for (int q = 0; q < 300; q++) {
    if (q % 3 == 0) gen_lattice(&r, &s, 2);
    else if (q % 3 == 1) gen_cospherical(&r, &s);
    else gen_perturbed_grid(&r, &s);
    pset_ptrs(&s);
    random_ids(&r, ids);
    const double *const *p = s.ptr;
    const int o = i2m_orient3d(p[0], p[1], p[2], p[3]);
    const int is = i2m_insphere(p[0], p[1], p[2], p[3], p[4]);
    const int sos = i2m_insphere_sos(p[0], p[1], p[2], p[3], p[4], ids[0], ids[1], ids[2], ids[3], ids[4]);
    sos_nonzero += sos != 0;
    int pi[5] = {0, 1, 2, 3, 4};
    do { /* all 120 permutations of the (point, id) pairs */
      const int par = perm_parity(pi, 5);
      const double *a = p[pi[0]], *b = p[pi[1]], *c = p[pi[2]], *d = p[pi[3]], *e = p[pi[4]];
      if (pi[4] == 4) bad_o3 += i2m_orient3d(a, b, c, d) != par * o;
      bad_isp += i2m_insphere(a, b, c, d, e) != par * is;
      const int sp = i2m_insphere_sos(a, b, c, d, e, ids[pi[0]], ids[pi[1]], ids[pi[2]], ids[pi[3]], ids[pi[4]]);
      bad_sos += sp != par * sos;
      flips += pi[4] == 4 && par < 0 && sos != 0 && sp == -sos;
    } while (next_perm(pi, 5));
    /* relabelling by an increasing map keeps the sign */
    i2m_gidx_t ids2[5];
    for (int i = 0; i < 5; i++) ids2[i] = 3 * ids[i] + 1000000000000LL;
    bad_relabel += i2m_insphere_sos(p[0], p[1], p[2], p[3], p[4], ids2[0], ids2[1], ids2[2], ids2[3], ids2[4]) != sos;
    /* any relabelling agrees with the reference for the new ids */
    random_ids(&r, ids2);
    const int rs = ref_insphere_sos(p, ids2);
    bad_relabel += i2m_insphere_sos(p[0], p[1], p[2], p[3], p[4], ids2[0], ids2[1], ids2[2], ids2[3], ids2[4]) != rs;
  }
  printf("\n    permutations: %ld sos non-zero of 300, %ld odd (a,b,c,d) permutations flipped\n",
         sos_nonzero, flips);
  CU_ASSERT_EQUAL(bad_o3, 0);
  CU_ASSERT_EQUAL(bad_isp, 0);
  CU_ASSERT_EQUAL(bad_sos, 0);
  CU_ASSERT_EQUAL(bad_relabel, 0);
  CU_ASSERT(sos_nonzero > 200 && flips > 1000);
}

/* Shewchuk / Kettner et al. style: a point on a 1-ulp grid around a plane or a sphere.
 * Naive double evaluation gets many signs wrong; the robust predicates get none. */
static void test_ulp_grid(void)
{
  const double u = 0x1p-53; /* ulp of 0.5 */
  const double b[3] = {12, 12, 0}, c[3] = {24, 24, 0}, d[3] = {0, 0, 1}; /* plane x = y */
  long o3_fast_wrong = 0, o3_wrong = 0, n = 0;
  long o2_fast_wrong = 0, o2_wrong = 0;
  for (int i = 0; i < 64; i++)
    for (int j = 0; j < 64; j++) {
      const double a[3] = {0.5 + i * u, 0.5 + j * u, 0.5};
      const int ref = ref_orient3d(a, b, c, d);
      o3_wrong += i2m_orient3d(a, b, c, d) != ref;
      o3_fast_wrong += sgn(i2m_orient3d_fast(a, b, c, d)) != ref;
      /* the 2D classic: (a, (12,12), (24,24)) projected on z */
      const int ref2 = ref_orient2d_proj(a, b, c, 2);
      o2_wrong += i2m_orient2d_proj(a, b, c, 2) != ref2;
      const double ux = b[0] - a[0], uy = b[1] - a[1], vx = c[0] - a[0], vy = c[1] - a[1];
      o2_fast_wrong += sgn(ux * vy - uy * vx) != ref2;
      n++;
    }
  /* sphere of radius 3 about (1000,1000,1000) through the integer points (1,2,2),...;
   * e near (1002,1002,1001) on a 1-ulp grid */
  const double C = 1000.0, ul = 0x1p-43; /* ulp of 1002 */
  const double sa[3] = {C + 1, C + 2, C + 2}, sb[3] = {C + 2, C + 1, C - 2};
  const double sc[3] = {C - 2, C + 2, C - 1}, sd[3] = {C + 2, C - 2, C + 1};
  long is_fast_wrong = 0, is_wrong = 0, sos_wrong = 0, m = 0;
  const i2m_gidx_t ids[5] = {10, 20, 30, 40, 5};
  for (int i = -32; i < 32; i++)
    for (int j = -32; j < 32; j++) {
      const double e[3] = {C + 2 + i * ul, C + 2 + j * ul, C + 1};
      const double *p[5] = {sa, sb, sc, sd, e};
      const int ref = ref_insphere(p);
      is_wrong += i2m_insphere(sa, sb, sc, sd, e) != ref;
      is_fast_wrong += sgn(i2m_insphere_fast(sa, sb, sc, sd, e)) != ref;
      const int rs = ref ? ref : ref_insphere_sos(p, ids);
      sos_wrong += i2m_insphere_sos(sa, sb, sc, sd, e, 10, 20, 30, 40, 5) != rs;
      m++;
    }
  printf("\n    1-ulp grids: orient3d naive wrong %ld/%ld robust wrong %ld; orient2d naive wrong "
         "%ld robust wrong %ld; insphere naive wrong %ld/%ld robust wrong %ld sos wrong %ld\n",
         o3_fast_wrong, n, o3_wrong, o2_fast_wrong, o2_wrong, is_fast_wrong, m, is_wrong, sos_wrong);
  CU_ASSERT(o3_fast_wrong > 0);
  CU_ASSERT(o2_fast_wrong > 0);
  CU_ASSERT(is_fast_wrong > 0);
  CU_ASSERT_EQUAL(o3_wrong, 0);
  CU_ASSERT_EQUAL(o2_wrong, 0);
  CU_ASSERT_EQUAL(is_wrong, 0);
  CU_ASSERT_EQUAL(sos_wrong, 0);
}

/* Random points in a cube: the filter path; the robust and naive signs agree when the
 * naive value is far from zero, and the references agree everywhere. */
static void test_random_generic(void)
{
  rng_t r = {13};
  pset_t s;
  stats_t st = {0};
  i2m_gidx_t ids[5];
  for (int q = 0; q < 2000; q++) {
    for (int i = 0; i < 5; i++)
      for (int c = 0; c < 3; c++) s.p[i][c] = rng_unit(&r);
    pset_ptrs(&s);
    random_ids(&r, ids);
    check_query(s.ptr, ids, 1, &st);
  }
  print_stats("random unit cube", &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
  CU_ASSERT_EQUAL(st.fast_wrong, 0);
}

/* Nearly degenerate sets whose coordinate differences are inexact: points computed in
 * floating point on a plane o + s u + t v, or on a sphere c + r n/|n|, so they are off by
 * rounding errors only.  The filter has to decline the close calls and exact arithmetic on
 * non-representable differences decides them. */
static void test_rounded_near_degenerate(void)
{
  rng_t r = {14};
  pset_t s;
  stats_t st = {0}, st2 = {0};
  i2m_gidx_t ids[5];
  for (int q = 0; q < 4000; q++) {
    double o[3], u[3], v[3];
    for (int c = 0; c < 3; c++) {
      o[c] = 100.0 * rng_sym(&r);
      u[c] = rng_sym(&r);
      v[c] = rng_sym(&r);
    }
    for (int i = 0; i < 5; i++) {
      const double a = 10.0 * rng_sym(&r), b = 10.0 * rng_sym(&r);
      for (int c = 0; c < 3; c++) s.p[i][c] = o[c] + a * u[c] + b * v[c];
    }
    pset_ptrs(&s);
    random_ids(&r, ids);
    check_query(s.ptr, ids, 0, &st);
  }
  print_stats("rounded near-coplanar", &st);
  CU_ASSERT_EQUAL(st.wrong, 0);
  CU_ASSERT(st.fast_wrong > 100);
  for (int q = 0; q < 4000; q++) {
    double c0[3];
    const double rad = 0.5 + 10.0 * rng_unit(&r);
    for (int c = 0; c < 3; c++) c0[c] = 100.0 * rng_sym(&r);
    for (int i = 0; i < 5; i++) {
      double n[3], nn;
      do {
        for (int c = 0; c < 3; c++) n[c] = rng_sym(&r);
        nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      } while (nn < 0.1 || nn > 1.0);
      for (int c = 0; c < 3; c++) s.p[i][c] = c0[c] + rad * (n[c] / nn);
    }
    pset_ptrs(&s);
    random_ids(&r, ids);
    check_query(s.ptr, ids, 0, &st2);
  }
  print_stats("rounded near-cospherical", &st2);
  CU_ASSERT_EQUAL(st2.wrong, 0);
  CU_ASSERT(st2.fast_wrong > 100);
}

/* Scales where the products of the filter underflow (subnormal results with absolute
 * errors): the range checks of the filters must send these to the exact path.  Uniform
 * scales around the underflow threshold of each predicate, and for orient3d a huge z
 * difference multiplying subnormal xy-products (zmax check). */
static void test_filter_underflow(void)
{
  stats_t st1 = {0}, st2 = {0}, st3 = {0};
  run_family("insphere underflow zone (2^-230..2^-200)", 15, 2000, -230, -200, &st1);
  run_family("orient3d underflow zone (2^-365..2^-340)", 16, 1500, -365, -340, &st2);
  run_family("orient2d underflow zone (2^-545..2^-520)", 17, 1500, -545, -520, &st3);
  CU_ASSERT_EQUAL(st1.wrong + st2.wrong + st3.wrong, 0);
  /* xy-minors x2 y3 - x3 y2 of about 2^-1074 whose two products are subnormal (rounded to
   * multiples of 2^-1074), multiplied by a huge z in orient3d; the same minor alone is an
   * orient2d.  Per axis these coordinates are within the documented exact range. */
  rng_t r = {18};
  long wrong = 0, naive_wrong = 0, wrong2 = 0, naive_wrong2 = 0;
  const double a[3] = {0, 0, 0};
  for (int q = 0; q < 3000; q++) {
    const double Z = ldexp(1.0, rng_int(&r, 460, 620));
    const double b[3] = {0, 0, Z};
    const double x2 = ldexp(1.0 + rng_unit(&r), -537), y2 = ldexp(1.0 + rng_unit(&r), -537);
    const double x3 = ldexp(1.0 + rng_unit(&r), -537);
    const double y3 = y2 * x3 / x2 + ldexp(rng_sym(&r), -536);
    const double c[3] = {x2, y2, 0}, d[3] = {x3, y3, 0};
    const int ref = ref_orient3d(a, b, c, d);
    wrong += i2m_orient3d(a, b, c, d) != ref;
    naive_wrong += sgn(i2m_orient3d_fast(a, b, c, d)) != ref;
    const int ref2 = ref_orient2d_proj(a, c, d, 2);
    wrong2 += i2m_orient2d_proj(a, c, d, 2) != ref2;
    naive_wrong2 += sgn(x2 * y3 - x3 * y2) != ref2;
  }
  printf("\n    huge z times subnormal xy-minors: orient3d robust wrong %ld, naive wrong %ld; "
         "orient2d robust wrong %ld, naive wrong %ld (of 3000)\n",
         wrong, naive_wrong, wrong2, naive_wrong2);
  CU_ASSERT_EQUAL(wrong, 0);
  CU_ASSERT_EQUAL(wrong2, 0);
  CU_ASSERT(naive_wrong > 0 && naive_wrong2 > 0);
  /* two huge z differences times subnormal minors: uz m(v,w) - vz m(u,w) can cancel */
  long wrong3 = 0, naive_wrong3 = 0;
  for (int q = 0; q < 3000; q++) {
    const double Z1 = ldexp(1.0 + rng_unit(&r), 560), Z2 = ldexp(1.0 + rng_unit(&r), 560);
    double m[6];
    for (int k = 0; k < 6; k++) m[k] = ldexp(1.0 + rng_unit(&r), -537);
    const double b[3] = {m[0], m[1], Z1}, c[3] = {m[2], m[3], Z2};
    /* d chosen so that Z1 m(c,d) ~ Z2 m(b,d) */
    const double d[3] = {m[4], m[4] * (Z1 * m[3] - Z2 * m[1]) / (Z1 * m[2] - Z2 * m[0]) +
                                   ldexp(rng_sym(&r), -530), 0};
    const int ref = ref_orient3d(a, b, c, d);
    wrong3 += i2m_orient3d(a, b, c, d) != ref;
    naive_wrong3 += sgn(i2m_orient3d_fast(a, b, c, d)) != ref;
  }
  /* the 1-ulp grid examples scaled so that the filter products are subnormal */
  long wrong4 = 0, naive_wrong4 = 0;
  for (int i = 0; i < 32; i++)
    for (int j = 0; j < 32; j++) {
      const double u = 0x1p-53;
      const double p2[3] = {ldexp(0.5 + i * u, -530), ldexp(0.5 + j * u, -530), 0};
      const double q2[3] = {ldexp(12.0, -530), ldexp(12.0, -530), 0};
      const double r2[3] = {ldexp(24.0, -530), ldexp(24.0, -530), 0};
      const int ref2 = ref_orient2d_proj(p2, q2, r2, 2);
      wrong4 += i2m_orient2d_proj(p2, q2, r2, 2) != ref2;
      naive_wrong4 += sgn((q2[0] - p2[0]) * (r2[1] - p2[1]) - (q2[1] - p2[1]) * (r2[0] - p2[0])) != ref2;
      const double p3[3] = {ldexp(0.5 + i * u, -356), ldexp(0.5 + j * u, -356), ldexp(0.5, -356)};
      const double q3[3] = {ldexp(12.0, -356), ldexp(12.0, -356), 0};
      const double r3[3] = {ldexp(24.0, -356), ldexp(24.0, -356), 0};
      const double s3[3] = {0, 0, ldexp(1.0, -356)};
      const int ref3 = ref_orient3d(p3, q3, r3, s3);
      wrong4 += i2m_orient3d(p3, q3, r3, s3) != ref3;
      naive_wrong4 += sgn(i2m_orient3d_fast(p3, q3, r3, s3)) != ref3;
    }
  printf("    two huge z: robust wrong %ld, naive wrong %ld; scaled 1-ulp grids: robust wrong %ld, "
         "naive wrong %ld\n", wrong3, naive_wrong3, wrong4, naive_wrong4);
  CU_ASSERT_EQUAL(wrong3, 0);
  CU_ASSERT_EQUAL(wrong4, 0);
  CU_ASSERT(naive_wrong3 > 0 && naive_wrong4 > 0);
}

static const test_case_t cases[] = {
    {"sign conventions", test_conventions},
    {"random unit cube", test_random_generic},
    {"1e-12 perturbed integer grid", test_perturbed_grid},
    {"lattice points (degenerate)", test_lattice},
    {"cospherical Pythagorean quadruples", test_cospherical},
    {"plane with 2^-50 perturbations", test_plane},
    {"one ulp off plane / sphere", test_ulp_off},
    {"huge coordinates", test_huge},
    {"tiny coordinates", test_tiny},
    {"mixed scales", test_mixed_scales},
    {"permutations and relabelling", test_permutations},
    {"1-ulp grids (naive fails, robust does not)", test_ulp_grid},
    {"rounded near-coplanar / near-cospherical", test_rounded_near_degenerate},
    {"filter under underflow", test_filter_underflow},
};

TEST_MAIN("geom_predicates", cases)
