/* Unit tests of the Delaunay kernel (layer 3): validity and the empty-sphere property on
 * random, lattice (fully cospherical), spherical and near-degenerate point sets; the same
 * tetrahedralization whatever the insertion order; removal of random subsets giving exactly
 * the tetrahedralization of what remains; duplicates refused. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "i2m/dt.h"
#include "i2m/predicates.h"
#include "test_util.h"

#ifdef I2M_DEBUG /* sanitizer and debug builds: smaller sets, same properties */
#define N_RANDOM 60000
#define LATTICE 16
#else
#define N_RANDOM 1000000
#define LATTICE 40
#endif

static uint64_t rng_state = 88172645463325252ull;
static double urand(void)
{
  rng_state ^= rng_state << 13;
  rng_state ^= rng_state >> 7;
  rng_state ^= rng_state << 17;
  return (double)(rng_state >> 11) * (1.0 / 9007199254740992.0);
}

static i2m_dt_t *make_dt(double lo, double hi, uint32_t nv)
{
  double L[3] = {lo, lo, lo}, H[3] = {hi, hi, hi};
  i2m_dt_t *dt = NULL;
  CU_ASSERT_FATAL(i2m_dt_create(L, H, nv, 0, &dt) == I2M_OK);
  return dt;
}

static void assert_valid(const i2m_dt_t *dt)
{
  i2m_err_t err = i2m_dt_check(dt, true);
  if (err != I2M_OK) fprintf(stderr, "check failed: %s\n", i2m_error_message());
  CU_ASSERT_EQUAL_FATAL(err, I2M_OK);
}

/* Inserts points one by one in the given order with explicit global ids (no BRIO). */
static void insert_in_order(i2m_dt_t *dt, const double *xyz, const int64_t *gid, const uint32_t *order, size_t n)
{
  i2m_dt_ctx_t ctx;
  CU_ASSERT_FATAL(i2m_dt_ctx_init(&ctx, dt, 1, false) == I2M_OK);
  uint32_t hint = 0, v;
  while (!i2m_dt_alive(dt, hint)) hint++;
  for (size_t r = 0; r < n; r++) {
    uint32_t k = order ? order[r] : (uint32_t)r;
    i2m_dt_status_t st = i2m_dt_insert_walk(&ctx, xyz + 3 * k, gid[k], I2M_VK_FREE, hint, &v);
    CU_ASSERT_EQUAL_FATAL(st, I2M_DT_OK);
    hint = ctx.newt[0];
  }
  i2m_dt_ctx_free(&ctx);
}

static void test_random_points(void)
{
  size_t n = N_RANDOM;
  double *xyz = malloc(3 * n * sizeof *xyz);
  for (size_t i = 0; i < 3 * n; i++) xyz[i] = urand();
  i2m_dt_t *dt = make_dt(-3, 4, (uint32_t)n);
  int64_t ndup = -1;
  CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n, 8, 1, NULL, &ndup) == I2M_OK);
  CU_ASSERT_EQUAL(ndup, 0);
  assert_valid(dt);
  int64_t nt = i2m_dt_count_tets(dt);
  CU_ASSERT(nt > 6 * (int64_t)n && nt < 7 * (int64_t)n); /* about 6.7 tets per point */
  i2m_dt_destroy(&dt);
  free(xyz);
}

static double *lattice_points(int m, double h, size_t *n)
{
  *n = (size_t)m * m * m;
  double *xyz = malloc(3 * *n * sizeof *xyz);
  size_t k = 0;
  for (int i = 0; i < m; i++)
    for (int j = 0; j < m; j++)
      for (int l = 0; l < m; l++) {
        xyz[3 * k] = i * h;
        xyz[3 * k + 1] = j * h;
        xyz[3 * k + 2] = l * h;
        k++;
      }
  return xyz;
}

/* A lattice: every unit cube's 8 corners are cospherical; only the perturbation decides. */
static void test_lattice_order_independent(void)
{
  size_t n;
  double *xyz = lattice_points(LATTICE, 1.0, &n);
  uint64_t sums[3];
  int64_t counts[3];
  for (int run = 0; run < 3; run++) {
    i2m_dt_t *dt = make_dt(-64, 128, (uint32_t)n);
    CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n, 8, 1000 + (uint64_t)run, NULL, NULL) == I2M_OK);
    if (run == 0) assert_valid(dt);
    sums[run] = i2m_dt_checksum(dt, &counts[run]);
    i2m_dt_destroy(&dt);
  }
  /* and a plain sequential order (no sorting), reversed */
  int64_t *gid = malloc(n * sizeof *gid);
  uint32_t *order = malloc(n * sizeof *order);
  for (size_t i = 0; i < n; i++) {
    gid[i] = 8 + (int64_t)i;
    order[i] = (uint32_t)(n - 1 - i);
  }
  i2m_dt_t *dt = make_dt(-64, 128, (uint32_t)n);
  insert_in_order(dt, xyz, gid, order, n);
  assert_valid(dt);
  int64_t c4;
  uint64_t s4 = i2m_dt_checksum(dt, &c4);
  i2m_dt_destroy(&dt);
  CU_ASSERT_EQUAL(sums[0], sums[1]);
  CU_ASSERT_EQUAL(sums[0], sums[2]);
  CU_ASSERT_EQUAL(sums[0], s4);
  CU_ASSERT_EQUAL(counts[0], counts[1]);
  CU_ASSERT_EQUAL(counts[0], c4);
  free(gid);
  free(order);
  free(xyz);
}

/* Random points in the same set, inserted in three orders: identical tetrahedralizations. */
static void test_random_order_independent(void)
{
  size_t n = N_RANDOM / 10;
  double *xyz = malloc(3 * n * sizeof *xyz);
  for (size_t i = 0; i < 3 * n; i++) xyz[i] = urand();
  uint64_t s[3];
  for (int run = 0; run < 3; run++) {
    i2m_dt_t *dt = make_dt(-3, 4, (uint32_t)n);
    CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n, 8, 77 + (uint64_t)run * 1000, NULL, NULL) == I2M_OK);
    s[run] = i2m_dt_checksum(dt, NULL);
    i2m_dt_destroy(&dt);
  }
  CU_ASSERT_EQUAL(s[0], s[1]);
  CU_ASSERT_EQUAL(s[0], s[2]);
  free(xyz);
}

/* Points exactly on a sphere (integer points with x^2+y^2+z^2 = R^2) plus random points on
 * a sphere: massively cospherical. */
static void test_sphere_points(void)
{
  const int R = 65; /* 65^2 = 4225 has many representations as a sum of three squares */
  size_t cap = 20000, n = 0;
  double *xyz = malloc(3 * cap * sizeof *xyz);
  for (int x = -R; x <= R; x++)
    for (int y = -R; y <= R; y++) {
      int z2 = R * R - x * x - y * y;
      if (z2 < 0) continue;
      int z = (int)lround(sqrt((double)z2));
      if (z * z != z2) continue;
      for (int sgn = -1; sgn <= 1; sgn += 2) {
        if (z == 0 && sgn > 0) continue;
        xyz[3 * n] = x;
        xyz[3 * n + 1] = y;
        xyz[3 * n + 2] = sgn * z;
        n++;
      }
    }
  size_t nexact = n;
  while (n < 6000) { /* random directions, rounded: near-cospherical */
    double u = 2 * urand() - 1, phi = 2 * I2M_PI * urand(), s = sqrt(1 - u * u);
    xyz[3 * n] = 30 * s * cos(phi);
    xyz[3 * n + 1] = 30 * s * sin(phi);
    xyz[3 * n + 2] = 30 * u;
    n++;
  }
  CU_ASSERT(nexact > 100);
  i2m_dt_t *dt = make_dt(-200, 200, (uint32_t)n);
  int64_t ndup;
  CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n, 8, 5, NULL, &ndup) == I2M_OK);
  CU_ASSERT_EQUAL(ndup, 0);
  assert_valid(dt);
  i2m_dt_destroy(&dt);
  free(xyz);
}

/* A grid perturbed by 1e-12: nearly degenerate everywhere. */
static void test_perturbed_grid(void)
{
  size_t n;
  double *xyz = lattice_points(LATTICE / 2, 1.0, &n);
  for (size_t i = 0; i < 3 * n; i++) xyz[i] += 1e-12 * (2 * urand() - 1);
  i2m_dt_t *dt = make_dt(-64, 128, (uint32_t)n);
  CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n, 8, 9, NULL, NULL) == I2M_OK);
  assert_valid(dt);
  i2m_dt_destroy(&dt);
  free(xyz);
}

/* n random points in [0, 10)^3 (malloc'd). */
static double *random_points(size_t n)
{
  double *xyz = malloc(3 * n * sizeof *xyz);
  for (size_t i = 0; i < 3 * n; i++) xyz[i] = 10 * urand();
  return xyz;
}

/* The tetrahedralization of n points with global ids 8 + i (*gid), their slots in *vid, with
 * pay bytes of payload per tet. */
static i2m_dt_t *build_with_ids(const double *xyz, size_t n, uint64_t seed, size_t pay, int64_t **gid, uint32_t **vid)
{
  *gid = malloc(n * sizeof **gid);
  *vid = malloc(n * sizeof **vid);
  for (size_t i = 0; i < n; i++) (*gid)[i] = 8 + (int64_t)i;
  const double L[3] = {-64, -64, -64}, H[3] = {128, 128, 128};
  i2m_dt_t *dt = NULL;
  CU_ASSERT_FATAL(i2m_dt_create(L, H, (uint32_t)n, pay, &dt) == I2M_OK);
  CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n, 8, seed, *vid, NULL) == I2M_OK);
  return dt;
}

/* *dt (destroyed here) must be valid and hold the very tets of the tetrahedralization built
 * anew, point by point, of the points not dropped (drop NULL: all), with their global ids. */
static void assert_as_built_anew(i2m_dt_t **dt, const double *xyz, const int64_t *gid, const char *drop, size_t n)
{
  assert_valid(*dt);
  int64_t c1, c2;
  const uint64_t s1 = i2m_dt_checksum(*dt, &c1);
  i2m_dt_destroy(dt);
  double *rest = malloc(3 * n * sizeof *rest + 1);
  int64_t *rgid = malloc(n * sizeof *rgid + 1);
  size_t m = 0;
  for (size_t i = 0; i < n; i++)
    if (!drop || !drop[i]) {
      memcpy(rest + 3 * m, xyz + 3 * i, 3 * sizeof *rest);
      rgid[m++] = gid[i];
    }
  i2m_dt_t *anew = make_dt(-64, 128, (uint32_t)m);
  insert_in_order(anew, rest, rgid, NULL, m);
  const uint64_t s2 = i2m_dt_checksum(anew, &c2);
  i2m_dt_destroy(&anew);
  CU_ASSERT_EQUAL(c1, c2);
  CU_ASSERT_EQUAL(s1, s2);
  free(rest);
  free(rgid);
}

/* Insert a set, remove a random subset; the result must be valid, Delaunay, and identical
 * (checksum) to the tetrahedralization of the remaining points built from scratch. */
static void removal_case(double *xyz, size_t n, double frac, uint64_t seed)
{
  int64_t *gid;
  uint32_t *vid;
  i2m_dt_t *dt = build_with_ids(xyz, n, seed, 0, &gid, &vid);
  i2m_dt_ctx_t ctx;
  CU_ASSERT_FATAL(i2m_dt_ctx_init(&ctx, dt, 1, false) == I2M_OK);
  char *removed = calloc(n, 1);
  size_t nremoved = 0;
  rng_state ^= seed * 0x9E3779B97F4A7C15ull;
  for (size_t i = 0; i < n; i++) {
    if (urand() >= frac) continue;
    i2m_dt_status_t st = i2m_dt_remove(&ctx, vid[i]);
    CU_ASSERT_EQUAL_FATAL(st, I2M_DT_OK);
    removed[i] = 1;
    nremoved++;
  }
  CU_ASSERT(nremoved > 0);
  /* removing a dead vertex or a box corner changes nothing */
  for (size_t i = 0; i < n; i++)
    if (removed[i]) {
      CU_ASSERT_EQUAL(i2m_dt_remove(&ctx, vid[i]), I2M_DT_STALE);
      break;
    }
  CU_ASSERT_EQUAL(i2m_dt_remove(&ctx, 3), I2M_DT_STALE);
  i2m_dt_ctx_free(&ctx);
  assert_as_built_anew(&dt, xyz, gid, removed, n);
  free(removed);
  free(gid);
  free(vid);
}

/* A tet's payload: a hash of its sorted global ids (it must follow the tet wherever it goes). */
static uint32_t tet_tag(const i2m_dt_t *dt, uint32_t t)
{
  i2m_gidx_t g[4];
  for (int i = 0; i < 4; i++) g[i] = i2m_dt_gid(dt, dt->tv[4 * (size_t)t + i]);
  for (int i = 1; i < 4; i++)
    for (int j = i; j > 0 && g[j - 1] > g[j]; j--) {
      const i2m_gidx_t x = g[j];
      g[j] = g[j - 1];
      g[j - 1] = x;
    }
  uint64_t h = 1469598103934665603ull;
  for (int i = 0; i < 4; i++) h = (h ^ (uint64_t)g[i]) * 1099511628211ull;
  return (uint32_t)(h >> 17);
}

/* The mean distance between the slots of neighbouring tets. */
static double mean_neighbour_gap(const i2m_dt_t *dt)
{
  double sum = 0;
  int64_t n = 0;
  for (uint32_t t = 0; t < i2m_dt_ntets_slots(dt); t++) {
    if (!i2m_dt_alive(dt, t)) continue;
    for (int i = 0; i < 4; i++) {
      const uint32_t f = dt->tn[4 * (size_t)t + i];
      if (f >= I2M_DT_REMOTE) continue;
      sum += fabs((double)(f >> 2) - (double)t);
      n++;
    }
  }
  return n ? sum / (double)n : 0;
}

/* Random points, a third removed (dead slots), the tets renumbered along the Morton curve: the
 * same valid tetrahedralization (checksum), compact (no dead slot), each payload with its tet,
 * neighbours far closer in the arrays; and insertions after it work as before. */
static void test_sort_tets(void)
{
  const size_t n = N_RANDOM / 20;
  double *xyz = random_points(n);
  int64_t *gid;
  uint32_t *vid;
  i2m_dt_t *dt = build_with_ids(xyz, n, 21, sizeof(uint32_t), &gid, &vid);
  i2m_dt_ctx_t ctx;
  CU_ASSERT_FATAL(i2m_dt_ctx_init(&ctx, dt, 1, false) == I2M_OK);
  for (size_t i = 0; i < n; i += 3) CU_ASSERT_EQUAL_FATAL(i2m_dt_remove(&ctx, vid[i]), I2M_DT_OK);
  i2m_dt_ctx_flush(&ctx);
  for (uint32_t t = 0; t < i2m_dt_ntets_slots(dt); t++) {
    const uint32_t tag = tet_tag(dt, t);
    if (i2m_dt_alive(dt, t)) memcpy(i2m_dt_payload(dt, t), &tag, sizeof tag);
  }
  int64_t c0, c1;
  const uint64_t s0 = i2m_dt_checksum(dt, &c0);
  const double gap0 = mean_neighbour_gap(dt);
  CU_ASSERT(dt->nfree_t > 0);
  const double lo[3] = {0, 0, 0}, hi[3] = {10, 10, 10};
  CU_ASSERT_FATAL(i2m_dt_sort_tets(dt, lo, hi) == I2M_OK);
  assert_valid(dt);
  CU_ASSERT_EQUAL(i2m_dt_checksum(dt, &c1), s0);
  CU_ASSERT_EQUAL(c1, c0);
  CU_ASSERT_EQUAL((int64_t)i2m_dt_ntets_slots(dt), c0); /* compact */
  CU_ASSERT_EQUAL(dt->nfree_t, 0);
  int moved_with = 1;
  for (uint32_t t = 0; t < i2m_dt_ntets_slots(dt); t++) {
    uint32_t tag;
    memcpy(&tag, i2m_dt_payload(dt, t), sizeof tag);
    moved_with &= tag == tet_tag(dt, t);
  }
  CU_ASSERT(moved_with);
  const double gap1 = mean_neighbour_gap(dt);
  CU_ASSERT(gap1 < gap0 / 4);
  for (size_t i = 0; i < n; i += 3) { /* the removed points back: as built anew */
    uint32_t v;
    CU_ASSERT_EQUAL_FATAL(i2m_dt_insert_walk(&ctx, xyz + 3 * i, gid[i], I2M_VK_FREE, 0, &v), I2M_DT_OK);
  }
  i2m_dt_ctx_free(&ctx);
  assert_as_built_anew(&dt, xyz, gid, NULL, n);
  free(xyz);
  free(gid);
  free(vid);
}

static void test_remove_random(void)
{
  size_t n = N_RANDOM / 20;
  double *xyz = random_points(n);
  removal_case(xyz, n, 0.3, 11);
  free(xyz);
}

static void test_remove_lattice(void)
{
  size_t n;
  double *xyz = lattice_points(LATTICE / 3, 1.0, &n);
  removal_case(xyz, n, 0.5, 12);
  free(xyz);
}

/* Moves random vertices: in place when i2m_dt_move says their tets stay Delaunay, else by a
 * removal and an insertion.  The result must be valid and the very tetrahedralization of the
 * moved points built from scratch (the same perturbation).  axis: each vertex moves at most
 * once, by step along an axis; else by up to `step` in every axis.  The moves done in place
 * and by reinsertion go to counts[2]. */
static void move_case(double *xyz, size_t n, size_t nmoves, double step, bool axis, uint64_t seed, size_t counts[2])
{
  int64_t *gid;
  uint32_t *vid;
  i2m_dt_t *dt = build_with_ids(xyz, n, seed, 0, &gid, &vid);
  char *moved = calloc(n, 1);
  i2m_dt_ctx_t ctx;
  CU_ASSERT_FATAL(i2m_dt_ctx_init(&ctx, dt, 1, false) == I2M_OK);
  rng_state ^= seed * 0x9E3779B97F4A7C15ull;
  size_t in_place = 0, reinserted = 0;
  for (size_t k = 0; k < nmoves; k++) {
    const size_t i = (size_t)(urand() * (double)n) % n;
    if (axis && moved[i]) continue;
    double p[3];
    for (int a = 0; a < 3; a++) p[a] = xyz[3 * i + a] + (axis ? 0.0 : step * (2 * urand() - 1));
    if (axis) p[(int)(urand() * 3) % 3] += step;
    const i2m_dt_status_t st = i2m_dt_move(&ctx, vid[i], p);
    i2m_dt_unlock_all(&ctx);
    if (st == I2M_DT_OK) {
      in_place++;
    } else {
      CU_ASSERT_EQUAL_FATAL(st, I2M_DT_NOT_IN_CONFLICT);
      CU_ASSERT_EQUAL_FATAL(i2m_dt_remove(&ctx, vid[i]), I2M_DT_OK);
      i2m_dt_unlock_all(&ctx);
      CU_ASSERT_EQUAL_FATAL(i2m_dt_insert_walk(&ctx, p, gid[i], I2M_VK_FREE, ctx.newt[0], &vid[i]), I2M_DT_OK);
      i2m_dt_unlock_all(&ctx);
      reinserted++;
    }
    memcpy(xyz + 3 * i, p, sizeof p);
    moved[i] = 1;
  }
  i2m_dt_ctx_free(&ctx);
  counts[0] = in_place;
  counts[1] = reinserted;
  assert_as_built_anew(&dt, xyz, gid, NULL, n);
  free(moved);
  free(gid);
  free(vid);
}

static void test_move_random(void)
{
  size_t n = N_RANDOM / 20;
  double *xyz = random_points(n);
  size_t counts[2];
  move_case(xyz, n, n, 0.1 * 10 / cbrt((double)n), false, 21, counts); /* (a tenth of the spacing) */
  CU_ASSERT(counts[0] > n / 20); /* (about 12% in place) */
  CU_ASSERT(counts[1] > n / 20);
  free(xyz);
}

/* On a lattice every configuration is cospherical: the triangulation is the perturbation's.
 * A vertex moved onto its own place keeps its tets (each test decided by the perturbation, as
 * when they were made); moved by an eighth of the spacing, it breaks ties otherwise and is
 * reinserted. */
static void test_move_lattice(void)
{
  size_t n, counts[2];
  double *xyz = lattice_points(LATTICE / 2, 1.0, &n);
  move_case(xyz, n, n / 2, 0.0, true, 22, counts);
  CU_ASSERT(counts[0] > 0);
  CU_ASSERT_EQUAL(counts[1], 0);
  move_case(xyz, n, n / 2, 0.125, true, 23, counts);
  CU_ASSERT(counts[1] > 0);
  free(xyz);
}

/* Every live tet's record (vertices, neighbours, generation, payload), slot by slot. */
typedef struct {
  uint32_t n, *tv, *tn, *meta;
  uint64_t *pay;
} tet_records_t;

static void records_take(const i2m_dt_t *dt, tet_records_t *s)
{
  s->n = i2m_dt_ntets_slots(dt);
  s->tv = malloc(4 * (size_t)s->n * sizeof *s->tv);
  s->tn = malloc(4 * (size_t)s->n * sizeof *s->tn);
  s->meta = malloc(s->n * sizeof *s->meta);
  s->pay = malloc(s->n * sizeof *s->pay);
  memcpy(s->tv, dt->tv, 4 * (size_t)s->n * sizeof *s->tv);
  memcpy(s->tn, dt->tn, 4 * (size_t)s->n * sizeof *s->tn);
  for (uint32_t t = 0; t < s->n; t++) {
    s->meta[t] = i2m_dt_meta(dt, t);
    memcpy(&s->pay[t], i2m_dt_payload(dt, t), sizeof *s->pay);
  }
}

/* The live tets of dt are exactly those of s, with the same records (dt may have more slots,
 * dead). */
static bool records_same(const i2m_dt_t *dt, const tet_records_t *s)
{
  for (uint32_t t = 0; t < i2m_dt_ntets_slots(dt); t++) {
    const bool was = t < s->n && !(s->meta[t] & I2M_TM_DEAD);
    if (i2m_dt_alive(dt, t) != was) return false;
    if (!was) continue;
    uint64_t pay;
    memcpy(&pay, i2m_dt_payload(dt, t), sizeof pay);
    if (memcmp(dt->tv + 4 * (size_t)t, s->tv + 4 * (size_t)t, 4 * sizeof *s->tv) != 0 ||
        memcmp(dt->tn + 4 * (size_t)t, s->tn + 4 * (size_t)t, 4 * sizeof *s->tn) != 0 || i2m_dt_meta(dt, t) != s->meta[t] ||
        pay != s->pay[t])
      return false;
  }
  return true;
}

static void records_free(tet_records_t *s)
{
  free(s->tv);
  free(s->tn);
  free(s->meta);
  free(s->pay);
}

/* Journaled insertions undone (i2m_dt_undo_insert) leave every live tet as it was, slot by
 * slot with its generation and payload, and the vertex slots as they were; as the sliver pass
 * uses them: a vertex taken out, points tried near it and undone, then the vertex put back,
 * which must give the triangulation built anew. */
static void undo_case(double *xyz, size_t n, size_t nvertices, uint64_t seed)
{
  int64_t *gid;
  uint32_t *vid;
  i2m_dt_t *dt = build_with_ids(xyz, n, seed, sizeof(uint64_t), &gid, &vid);
  for (uint32_t t = 0; t < i2m_dt_ntets_slots(dt); t++) { /* a payload to restore: a word per slot */
    const uint64_t w = 0x9E3779B97F4A7C15ull * (t + 1);
    memcpy(i2m_dt_payload(dt, t), &w, sizeof w);
  }
  i2m_dt_ctx_t ctx;
  CU_ASSERT_FATAL(i2m_dt_ctx_init(&ctx, dt, 1, false) == I2M_OK);
  rng_state ^= seed * 0x9E3779B97F4A7C15ull;
  size_t undone = 0;
  for (size_t k = 0; k < nvertices; k++) {
    const size_t i = (size_t)(urand() * (double)n) % n;
    CU_ASSERT_EQUAL_FATAL(i2m_dt_remove(&ctx, vid[i]), I2M_DT_OK);
    i2m_dt_unlock_all(&ctx);
    const uint32_t start = ctx.newt[0];
    tet_records_t before;
    records_take(dt, &before);
    const uint32_t nv = i2m_dt_nverts_slots(dt);
    ctx.journal = true;
    for (int m = 0; m < 8; m++) {
      double p[3];
      for (int a = 0; a < 3; a++) p[a] = xyz[3 * i + a] + 0.3 * (2 * urand() - 1);
      uint32_t v;
      const i2m_dt_status_t st = i2m_dt_insert_walk(&ctx, p, gid[i], I2M_VK_FREE, start, &v);
      i2m_dt_unlock_all(&ctx);
      CU_ASSERT_EQUAL_FATAL(st, I2M_DT_OK);
      for (uint32_t q = 0; q < ctx.nnew; q++) memset(i2m_dt_payload(dt, ctx.newt[q]), 0xA5, sizeof(uint64_t));
      CU_ASSERT_EQUAL_FATAL(i2m_dt_undo_insert(&ctx), I2M_OK);
      CU_ASSERT_EQUAL(dt->vkind[v], I2M_VK_DEAD);
      CU_ASSERT_FATAL(records_same(dt, &before));
      CU_ASSERT_EQUAL(i2m_dt_undo_insert(&ctx), I2M_ERR_INTERNAL); /* (nothing left to undo) */
      undone++;
    }
    ctx.journal = false;
    CU_ASSERT(i2m_dt_nverts_slots(dt) <= nv + 1);
    records_free(&before);
    CU_ASSERT_EQUAL_FATAL(i2m_dt_insert_walk(&ctx, xyz + 3 * i, gid[i], I2M_VK_FREE, start, &vid[i]), I2M_DT_OK);
    i2m_dt_unlock_all(&ctx);
  }
  i2m_dt_ctx_free(&ctx);
  CU_ASSERT_EQUAL(undone, 8 * nvertices);
  assert_as_built_anew(&dt, xyz, gid, NULL, n);
  free(gid);
  free(vid);
}

/* The accept hook: refused, nothing changed (every record as it was); accepted, the new tets
 * are exactly p joined to the faces the hook was shown, in their order.  While the cavity is
 * marked (another thread could be reading), each of its tets keeps the stamp it had before:
 * a record of a live tet is never taken for gone because of a search that may roll back. */
typedef struct {
  bool accept;
  uint32_t n, abc[4096][3];
  uint32_t ncav, marked, stamped; /* cavity tets when asked, those the hook saw marked, and those whose stamp was as before */
  const tet_records_t *before;
} hook_seen_t;

static bool record_hook(void *arg, const i2m_dt_ctx_t *ctx, const double p[3])
{
  hook_seen_t *h = arg;
  (void)p;
  h->n = ctx->nbnd < 4096 ? ctx->nbnd : 4096;
  for (uint32_t k = 0; k < h->n; k++) i2m_dt_cavity_face(ctx, k, h->abc[k]);
  h->ncav = ctx->ncav;
  h->marked = 0;
  h->stamped = 0;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t t = ctx->cav[k];
    h->marked += (i2m_dt_meta(ctx->dt, t) & I2M_TM_MARK) != 0;
    h->stamped += t < h->before->n && i2m_dt_stamp(ctx->dt, t) == h->before->meta[t];
  }
  return h->accept;
}

/* The hook tests' setting: a triangulation of random points with ids and payloads (records_take
 * reads one), a journaled context on it. */
typedef struct {
  size_t n;
  double *xyz;
  int64_t *gid;
  uint32_t *vid;
  i2m_dt_t *dt;
  i2m_dt_ctx_t ctx;
} hook_test_t;

static void hook_test_begin(hook_test_t *T, uint64_t seed)
{
  T->n = N_RANDOM / 50;
  T->xyz = random_points(T->n);
  T->dt = build_with_ids(T->xyz, T->n, seed, sizeof(uint64_t), &T->gid, &T->vid);
  CU_ASSERT_FATAL(i2m_dt_ctx_init(&T->ctx, T->dt, 1, false) == I2M_OK);
  T->ctx.journal = true;
}

/* Trial m (the hooks set): the tets' records into *before, then the insertion of a point
 * within 0.3 of a random input point. */
static i2m_dt_status_t hook_trial(hook_test_t *T, int m, tet_records_t *before, uint32_t *v)
{
  const size_t i = (size_t)(urand() * (double)T->n) % T->n;
  double p[3];
  for (int a = 0; a < 3; a++) p[a] = T->xyz[3 * i + a] + 0.3 * (2 * urand() - 1);
  records_take(T->dt, before);
  const i2m_dt_status_t st =
      i2m_dt_insert_walk(&T->ctx, p, (int64_t)(T->n + 100 + (size_t)m), I2M_VK_FREE, T->dt->vtet[T->vid[i]], v);
  i2m_dt_unlock_all(&T->ctx);
  return st;
}

/* The hook tests' end: the triangulation valid, everything freed. */
static void hook_test_end(hook_test_t *T, void *hook)
{
  CU_ASSERT_EQUAL(i2m_dt_check(T->dt, true), I2M_OK);
  free(hook);
  i2m_dt_ctx_free(&T->ctx);
  i2m_dt_destroy(&T->dt);
  free(T->gid);
  free(T->vid);
  free(T->xyz);
}

static void test_accept_hook(void)
{
  hook_test_t T;
  hook_test_begin(&T, 47);
  i2m_dt_t *dt = T.dt;
  hook_seen_t *h = calloc(1, sizeof *h);
  CU_ASSERT_FATAL(h != NULL);
  T.ctx.accept = record_hook;
  T.ctx.accept_arg = h;
  int refused = 0, accepted = 0;
  for (int m = 0; m < 200; m++) {
    tet_records_t before;
    h->before = &before;
    h->accept = m % 2 == 0;
    uint32_t v;
    const i2m_dt_status_t st = hook_trial(&T, m, &before, &v);
    CU_ASSERT(h->n > 0 && h->n < 4096);
    CU_ASSERT(h->ncav > 0 && h->marked == h->ncav); /* (the cavity is marked when the hook is asked) */
    CU_ASSERT_EQUAL(h->stamped, h->ncav);
    if (!h->accept) {
      CU_ASSERT_EQUAL(st, I2M_DT_REFUSED);
      CU_ASSERT(records_same(dt, &before)); /* (marks cleared too) */
      refused++;
    } else {
      CU_ASSERT_EQUAL_FATAL(st, I2M_DT_OK);
      CU_ASSERT_EQUAL(T.ctx.nnew, h->n);
      for (uint32_t k = 0; k < T.ctx.nnew && k < h->n; k++) {
        const uint32_t *tv = dt->tv + 4 * (size_t)T.ctx.newt[k];
        CU_ASSERT(tv[0] == h->abc[k][0] && tv[1] == h->abc[k][1] && tv[2] == h->abc[k][2] && tv[3] == v);
      }
      CU_ASSERT_EQUAL_FATAL(i2m_dt_undo_insert(&T.ctx), I2M_OK);
      CU_ASSERT(records_same(dt, &before));
      accepted++;
    }
    records_free(&before);
  }
  CU_ASSERT(refused == 100 && accepted == 100);
  hook_test_end(&T, h);
}

/* The face hook (zone mode): each boundary face shown once, in order, during the search, the
 * same faces the accept hook then sees (a face found to bound the cavity stays one); a refusal
 * by the face hook stops the search, changes nothing and spares the accept hook. */
typedef struct {
  uint32_t n, refuse_at, abc[4096][3];
  int accept_calls;
  bool all_seen;
} face_seen_t;

static bool face_hook(void *arg, const i2m_dt_ctx_t *ctx, uint32_t k, const double p[3])
{
  face_seen_t *h = arg;
  (void)p;
  CU_ASSERT_EQUAL(k, h->n); /* (in order, each once) */
  if (h->n < 4096) i2m_dt_cavity_face(ctx, k, h->abc[h->n]);
  h->n++;
  return k != h->refuse_at;
}

static bool faces_hook_accept(void *arg, const i2m_dt_ctx_t *ctx, const double p[3])
{
  face_seen_t *h = arg;
  (void)p;
  h->accept_calls++;
  h->all_seen = ctx->nbnd_seen == ctx->nbnd && ctx->nbnd == h->n;
  for (uint32_t k = 0; k < ctx->nbnd && k < 4096; k++) {
    uint32_t abc[3];
    i2m_dt_cavity_face(ctx, k, abc);
    h->all_seen &= abc[0] == h->abc[k][0] && abc[1] == h->abc[k][1] && abc[2] == h->abc[k][2];
  }
  return true;
}

static void test_accept_face_hook(void)
{
  hook_test_t T;
  hook_test_begin(&T, 53);
  i2m_dt_t *dt = T.dt;
  static const double everywhere[6] = {-1e6, -1e6, -1e6, 1e6, 1e6, 1e6};
  face_seen_t *h = calloc(1, sizeof *h);
  CU_ASSERT_FATAL(h != NULL);
  T.ctx.zone = everywhere;
  T.ctx.accept = faces_hook_accept;
  T.ctx.accept_face = face_hook;
  T.ctx.accept_arg = h;
  int refused = 0, accepted = 0;
  for (int m = 0; m < 200; m++) {
    tet_records_t before;
    memset(h, 0, sizeof *h);
    h->refuse_at = m % 2 == 0 ? 2 : UINT32_MAX;
    uint32_t v;
    const i2m_dt_status_t st = hook_trial(&T, m, &before, &v);
    if (h->refuse_at == 2) {
      CU_ASSERT_EQUAL(st, I2M_DT_REFUSED);
      CU_ASSERT_EQUAL(h->n, 3);
      CU_ASSERT_EQUAL(h->accept_calls, 0);
      CU_ASSERT(records_same(dt, &before));
      refused++;
    } else {
      CU_ASSERT_EQUAL_FATAL(st, I2M_DT_OK);
      CU_ASSERT_EQUAL(h->accept_calls, 1);
      CU_ASSERT(h->all_seen);
      CU_ASSERT_EQUAL_FATAL(i2m_dt_undo_insert(&T.ctx), I2M_OK);
      CU_ASSERT(records_same(dt, &before));
      accepted++;
    }
    records_free(&before);
  }
  CU_ASSERT(refused == 100 && accepted == 100);
  hook_test_end(&T, h);
}

static void test_undo_random(void)
{
  size_t n = N_RANDOM / 50;
  double *xyz = random_points(n);
  undo_case(xyz, n, n / 20, 31);
  free(xyz);
}

static void test_undo_lattice(void)
{
  size_t n;
  double *xyz = lattice_points(LATTICE / 3, 1.0, &n);
  undo_case(xyz, n, n / 10, 32);
  free(xyz);
}

static void test_remove_everything(void)
{
  size_t n = 500;
  double *xyz = malloc(3 * n * sizeof *xyz);
  for (size_t i = 0; i < 3 * n; i++) xyz[i] = 20 * urand();
  removal_case(xyz, n, 1.1, 13); /* all points: back to the empty box */
  free(xyz);
}

static void test_duplicates(void)
{
  double xyz[3 * 6] = {1, 1, 1, 2, 1, 1, 1, 2, 1, 1, 1, 2, 2, 1, 1, 1, 1, 1};
  i2m_dt_t *dt = make_dt(-10, 10, 8);
  int64_t ndup = 0;
  uint32_t vid[6];
  CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, 6, 8, 3, vid, &ndup) == I2M_OK);
  CU_ASSERT_EQUAL(ndup, 2);
  int dead = 0;
  for (int i = 0; i < 6; i++) dead += vid[i] == I2M_DT_NONE;
  CU_ASSERT_EQUAL(dead, 2);
  assert_valid(dt);
  i2m_dt_destroy(&dt);
}

/* Every point given twice (the copies in another order, on a lattice where everything is
 * cospherical and at random): each copy is refused as a duplicate, and the mesh is the one of
 * the points given once. */
static void test_duplicates_all(void)
{
  enum { N = 1000 };
  static double xyz[2 * 3 * N];
  for (int lattice = 0; lattice < 2; lattice++) {
    for (int i = 0; i < N; i++)
      for (int a = 0; a < 3; a++)
        xyz[3 * i + a] = lattice ? (double)((i / (a == 0 ? 1 : a == 1 ? 10 : 100)) % 10) : urand();
    for (int i = 0; i < N; i++) memcpy(xyz + 3 * (N + i), xyz + 3 * ((7 * i) % N), 3 * sizeof *xyz);
    int64_t ndup = 0, n1 = 0, n2 = 0;
    i2m_dt_t *once = make_dt(-10, 20, N), *twice = make_dt(-10, 20, 2 * N);
    CU_ASSERT_FATAL(i2m_dt_insert_points(once, xyz, N, 8, 5, NULL, NULL) == I2M_OK);
    CU_ASSERT_FATAL(i2m_dt_insert_points(twice, xyz, 2 * N, 8, 5, NULL, &ndup) == I2M_OK);
    CU_ASSERT_EQUAL(ndup, N);
    assert_valid(twice);
    /* the same vertices: 2N points make one BRIO round, where a point and its copy share a
     * Hilbert key and go in index order, so the first copy is the one kept */
    CU_ASSERT_EQUAL(i2m_dt_checksum(once, &n1), i2m_dt_checksum(twice, &n2));
    CU_ASSERT_EQUAL(n1, n2);
    i2m_dt_destroy(&once);
    i2m_dt_destroy(&twice);
  }
}

/* A vertex with a star of about six hundred tets (the centre of points on a sphere): removing
 * it grows the scratch for stars, re-inserting it needs a cavity as large; both must work
 * from whichever scratch the other left (a regression: the cavity's local-index rows once
 * outgrew their array after a large removal). */
static void test_large_star_remove_insert(void)
{
  const size_t n = 300; /* (its star: 2n - 4 = 596 tets; 600 points took 25 s, every test cospherical) */
  double *xyz = malloc(3 * (n + 1) * sizeof *xyz);
  CU_ASSERT_FATAL(xyz != NULL);
  for (size_t k = 0; k < n; k++) {
    double u = 2 * urand() - 1, phi = 2 * I2M_PI * urand(), s = sqrt(1 - u * u);
    xyz[3 * k] = 10 * s * cos(phi);
    xyz[3 * k + 1] = 10 * s * sin(phi);
    xyz[3 * k + 2] = 10 * u;
  }
  xyz[3 * n] = xyz[3 * n + 1] = xyz[3 * n + 2] = 0.01;
  i2m_dt_t *dt = make_dt(-100, 100, (uint32_t)n + 1);
  uint32_t *vid = malloc((n + 1) * sizeof *vid);
  CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n + 1, 8, 9, vid, NULL) == I2M_OK);
  int64_t nt0 = i2m_dt_count_tets(dt);
  uint64_t sum0 = i2m_dt_checksum(dt, NULL);
  i2m_dt_ctx_t ctx;
  CU_ASSERT_FATAL(i2m_dt_ctx_init(&ctx, dt, 1, false) == I2M_OK);
  for (int round = 0; round < 3; round++) {
    CU_ASSERT_EQUAL_FATAL(i2m_dt_remove(&ctx, vid[n]), I2M_DT_OK);
    CU_ASSERT(ctx.nnew > 500); /* the hole is re-triangulated by the sphere's points */
    i2m_dt_unlock_all(&ctx);
    assert_valid(dt);
    uint32_t start = ctx.newt[0];
    CU_ASSERT_EQUAL_FATAL(i2m_dt_insert_walk(&ctx, xyz + 3 * n, 8 + (int64_t)n, I2M_VK_FREE, start, &vid[n]),
                          I2M_DT_OK);
    CU_ASSERT(ctx.nnew > 500);
    assert_valid(dt);
    CU_ASSERT_EQUAL(i2m_dt_count_tets(dt), nt0);
    CU_ASSERT_EQUAL(i2m_dt_checksum(dt, NULL), sum0); /* the same tetrahedralization again */
  }
  i2m_dt_ctx_free(&ctx);
  i2m_dt_destroy(&dt);
  free(vid);
  free(xyz);
}

/* The empty box: 8 cospherical corners give 5 or 6 positive tets filling the box. */
/* The shifted frame: with a shift far larger than the coordinates, every point inserted is
 * snapped (moved by at most half an ulp of its world coordinate) so that coordinate + shift
 * is exact; the triangulation is valid and, translated to the world, every tet keeps its
 * positive orientation (exact predicate on the world coordinates). */
static void test_shifted_frame(void)
{
  const size_t n = N_RANDOM / 10;
  const double s[3] = {1e7, -3.3e6, 123456789.123};
  double *xyz = malloc(3 * n * sizeof *xyz), *world = NULL;
  uint32_t *vid = malloc(n * sizeof *vid);
  for (size_t i = 0; i < 3 * n; i++) xyz[i] = urand();
  i2m_dt_t *dt = make_dt(-3, 4, (uint32_t)n);
  i2m_dt_set_shift(dt, s);
  CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n, 8, 1, vid, NULL) == I2M_OK);
  assert_valid(dt);
  int64_t moved = 0;
  for (size_t i = 0; i < n; i++) {
    CU_ASSERT_FATAL(vid[i] != I2M_DT_NONE);
    const double *x = i2m_dt_xyz(dt, vid[i]);
    for (int a = 0; a < 3; a++) {
      CU_ASSERT((x[a] + s[a]) - s[a] == x[a]); /* the shift back is exact */
      CU_ASSERT(fabs(x[a] - xyz[3 * i + a]) <= 0.5 * (nextafter(fabs(s[a]) + 4, INFINITY) - (fabs(s[a]) + 4)));
      moved += x[a] != xyz[3 * i + a];
    }
  }
  CU_ASSERT(moved > (int64_t)n); /* (most coordinates are not on the world's grid) */
  uint32_t nv = i2m_dt_nverts_slots(dt), nt = i2m_dt_ntets_slots(dt);
  world = malloc(3 * (size_t)nv * sizeof *world);
  for (uint32_t v = 0; v < nv; v++)
    for (int a = 0; a < 3; a++) world[3 * v + a] = i2m_dt_xyz(dt, v)[a] + s[a];
  int64_t checked = 0, inverted = 0;
  for (uint32_t t = 0; t < nt; t++) {
    if (!i2m_dt_alive(dt, t)) continue;
    const uint32_t *v = dt->tv + 4 * (size_t)t;
    if (dt->vkind[v[0]] == I2M_VK_BOX || dt->vkind[v[1]] == I2M_VK_BOX || dt->vkind[v[2]] == I2M_VK_BOX ||
        dt->vkind[v[3]] == I2M_VK_BOX)
      continue; /* (the box corners were not inserted: not snapped) */
    checked++;
    inverted += i2m_orient3d(world + 3 * v[0], world + 3 * v[1], world + 3 * v[2], world + 3 * v[3]) <= 0;
  }
  CU_ASSERT(checked > 6 * (int64_t)n);
  CU_ASSERT_EQUAL(inverted, 0);
  i2m_dt_destroy(&dt);
  free(world);
  free(vid);
  free(xyz);
}

static void test_box(void)
{
  i2m_dt_t *dt = make_dt(-1, 2, 0);
  assert_valid(dt);
  int64_t n = i2m_dt_count_tets(dt);
  CU_ASSERT(n == 5 || n == 6);
  double vol = 0;
  for (uint32_t t = 0; t < i2m_dt_ntets_slots(dt); t++) {
    const uint32_t *v = dt->tv + 4 * t;
    vol += i2m_orient3d_fast(i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]), i2m_dt_xyz(dt, v[3])) / 6;
  }
  CU_ASSERT_DOUBLE_EQUAL(vol, 27.0, 1e-12);
  i2m_dt_destroy(&dt);
}

static const test_case_t cases[] = {
    {"virtual box", test_box},
    {"duplicates refused", test_duplicates},
    {"every point twice: each copy refused", test_duplicates_all},
    {"random points valid and Delaunay", test_random_points},
    {"random points: order-independent", test_random_order_independent},
    {"lattice (cospherical): order-independent", test_lattice_order_independent},
    {"points on a sphere", test_sphere_points},
    {"1e-12-perturbed grid", test_perturbed_grid},
    {"shifted frame: points snapped, shift back exact", test_shifted_frame},
    {"remove random subset of random points", test_remove_random},
    {"remove random subset of a lattice", test_remove_lattice},
    {"remove every point", test_remove_everything},
    {"tets renumbered along a Morton curve: the same mesh, compact, payloads with their tets", test_sort_tets},
    {"move random points: in place or reinserted, as if built anew", test_move_random},
    {"move lattice points: onto their places in place, by h/8 reinserted, as if built anew", test_move_lattice},
    {"large star: remove, insert again", test_large_star_remove_insert},
    {"journaled insertions undone: every tet back in its slot (random points)", test_undo_random},
    {"accept hook: a refusal changes nothing, an acceptance makes the tets it was shown", test_accept_hook},
    {"face hook: each face once during the search, the accept hook's faces; a refusal stops it", test_accept_face_hook},
    {"journaled insertions undone: every tet back in its slot (lattice)", test_undo_lattice},
};
TEST_MAIN("delaunay kernel", cases)
