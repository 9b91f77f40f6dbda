/* Delaunay layer: bulk insertion of a point set in BRIO order (biased randomized insertion
 * order: random rounds of geometrically growing size), each round sorted along a Hilbert
 * curve, every point located by a visibility walk from the previous insertion. */
#include "dt_impl.h"

#include <math.h>
#include <stdlib.h>

/* Bits per axis of the Hilbert keys: 10, so that a key (30 bits), a round number (3 bits) and
 * a point index (31 bits) pack into one 64-bit word; 2^30 cells leave few points per cell
 * at the sizes one process holds. */
#define HILBERT_BITS 10
#define ROUND_SHIFT 61
#define KEY_SHIFT 31

/* Hilbert index of a point with HILBERT_BITS-bit integer coordinates, after Skilling's
 * transpose formulation ("Programming the Hilbert curve", 2004): undo the excess work of the
 * rotations from the top bit down, Gray-encode, then interleave the bits. */
static uint64_t hilbert_key(uint32_t X[3])
{
  const uint32_t M = 1u << (HILBERT_BITS - 1);
  for (uint32_t Q = M; Q > 1; Q >>= 1) {
    const uint32_t P = Q - 1;
    for (int i = 0; i < 3; i++) { /* without branches: the bits are random, a branch would miss half the time */
      const uint32_t set = 0u - ((X[i] & Q) != 0); /* all ones when the bit is set */
      const uint32_t t = (X[0] ^ X[i]) & P & ~set;
      X[0] ^= (P & set) | t; /* set: invert the low bits of axis 0; else exchange those of axes 0 and i */
      X[i] ^= t;
    }
  }
  X[1] ^= X[0];
  X[2] ^= X[1];
  uint32_t t = 0;
  for (uint32_t Q = M; Q > 1; Q >>= 1) t ^= (Q - 1) & (0u - ((X[2] & Q) != 0));
  for (int i = 0; i < 3; i++) X[i] ^= t;
  uint64_t key = 0;
  for (int b = HILBERT_BITS - 1; b >= 0; b--)
    for (int i = 0; i < 3; i++) key = (key << 1) | ((X[i] >> b) & 1u);
  return key;
}

static uint64_t splitmix(uint64_t x)
{
  uint64_t z = x + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/* LSD radix sort of a[0..n) on bits [lo, 64), 11 bits a pass: 2048 buckets keep each pass's
 * scatter in the cache.  tmp: n words. */
#define RADIX_BITS 11
static void radix_sort_high(uint64_t *a, uint64_t *tmp, size_t n, int lo)
{
  size_t count[1u << RADIX_BITS];
  const uint64_t mask = (1u << RADIX_BITS) - 1;
  for (int shift = lo; shift < 64; shift += RADIX_BITS) {
    memset(count, 0, sizeof count);
    for (size_t i = 0; i < n; i++) count[(a[i] >> shift) & mask]++;
    size_t sum = 0;
    for (size_t d = 0; d <= mask; d++) {
      size_t c = count[d];
      count[d] = sum;
      sum += c;
    }
    for (size_t i = 0; i < n; i++) tmp[count[(a[i] >> shift) & mask]++] = a[i];
    memcpy(a, tmp, n * sizeof *a);
  }
}

/* BRIO (Amenta, Choi, Rote): each point joins a random round, the last holding ~87% of the
 * points and each earlier one 7.5 times fewer (the first at least 2048 unless all fit);
 * rounds go in order, each along a Hilbert curve.  A point's round is drawn from a hash of
 * its index, so the points are read in memory order (a shuffle would read them at random). */
static int brio_rounds(size_t n, double frac[8])
{
  int nr = 0;
  double size[8];
  for (double m = (double)n; nr < 7; m /= 7.5) {
    size[nr++] = m;
    if (m / 7.5 < 2048) break;
  }
  /* frac[k]: the fraction of points in rounds 0..k, rounds counted from the smallest */
  double acc = 0;
  for (int k = 0; k < nr; k++) {
    double part = k == nr - 1 ? size[0] : size[nr - 1 - k] - size[nr - k];
    acc += part;
    frac[k] = acc / (double)n;
  }
  frac[nr - 1] = 1.0;
  return nr;
}

static i2m_err_t brio_order(const double *xyz, size_t n, uint64_t seed, uint32_t **order_out)
{
  uint32_t *order = NULL;
  uint64_t *key = NULL, *tmp = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *order, &order));
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *key, &key));
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *tmp, &tmp));
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < n; i++)
    for (int a = 0; a < 3; a++) { /* (finite coordinates, checked by the caller) */
      double x = xyz[3 * i + a];
      lo[a] = x < lo[a] ? x : lo[a];
      hi[a] = x > hi[a] ? x : hi[a];
    }
  double extent = 0;
  for (int a = 0; a < 3; a++) extent = fmax(extent, hi[a] - lo[a]);
  double scale = extent > 0 ? ((1u << HILBERT_BITS) - 1) / extent : 0;
  double frac[8];
  int nr = brio_rounds(n, frac);
  for (size_t i = 0; i < n; i++) {
    double u = (double)(splitmix(seed ^ (i * 0xD1B54A32D192ED03ull)) >> 11) * 0x1p-53;
    uint64_t round = 0;
    while ((int)round < nr - 1 && u >= frac[round]) round++;
    uint32_t X[3];
    for (int a = 0; a < 3; a++) X[a] = (uint32_t)((xyz[3 * i + a] - lo[a]) * scale);
    key[i] = round << ROUND_SHIFT | hilbert_key(X) << KEY_SHIFT | i;
  }
  radix_sort_high(key, tmp, n, KEY_SHIFT);
  for (size_t i = 0; i < n; i++) order[i] = (uint32_t)(key[i] & ((1ull << KEY_SHIFT) - 1));
  *order_out = order;
  order = NULL;
done:
  i2m_free(&order);
  i2m_free(&key);
  i2m_free(&tmp);
  return err;
}

i2m_err_t i2m_dt_insert_points(i2m_dt_t *dt, const double *xyz, int64_t n, i2m_gidx_t gid0,
                               uint64_t seed, uint32_t *vid_out, int64_t *nduplicates)
{
  uint32_t *order = NULL;
  i2m_dt_ctx_t ctx;
  i2m_err_t err = I2M_OK;
  int64_t ndup = 0;
  if (nduplicates) *nduplicates = 0;
  if (n <= 0) return I2M_OK;
  I2M_CHECK(n < (int64_t)1 << 31, I2M_ERR_MEMORY, "too many points for one process (%lld)", (long long)n);
  for (int64_t i = 0; i < 3 * n; i++)
    I2M_CHECK(isfinite(xyz[i]), I2M_ERR_INPUT, "point %lld has a non-finite coordinate", (long long)(i / 3));
  for (int64_t i = 0; i < n; i++)
    for (int a = 0; a < 3; a++)
      I2M_CHECK(xyz[3 * i + a] > dt->box_lo[a] && xyz[3 * i + a] < dt->box_hi[a], I2M_ERR_INPUT,
                "point %lld lies outside the virtual box", (long long)i);
  uint64_t nv = i2m_dt_nverts_slots(dt) + (uint64_t)n, nt = (uint64_t)i2m_dt_ntets_slots(dt) + 7 * (uint64_t)n;
  I2M_CALL(i2m_dt_reserve(dt, (uint32_t)(nv < UINT32_MAX - 2 ? nv : UINT32_MAX - 2),
                          (uint32_t)(nt < (UINT32_MAX >> 2) - 1 ? nt : (UINT32_MAX >> 2) - 1)));
  double t0 = i2m_wtime();
  I2M_CALL(brio_order(xyz, (size_t)n, seed, &order));
  i2m_debug("bulk insertion: order of %lld points in %.3f s", (long long)n, i2m_wtime() - t0);
  I2M_CALL_GOTO(err, done, i2m_dt_ctx_init(&ctx, dt, 1, false));
  uint32_t hint = 0;
  while (!i2m_dt_alive(dt, hint)) hint++;
  for (int64_t r = 0; r < n; r++) {
    uint32_t k = order[r], v = I2M_DT_NONE;
    if (r + 8 < n) I2M_PREFETCH(xyz + 3 * (size_t)order[r + 8]); /* the points come in no memory order */
    i2m_dt_status_t st = i2m_dt_insert_walk(&ctx, xyz + 3 * (size_t)k, gid0 + k, I2M_VK_FREE, hint, &v);
    if (st == I2M_DT_OK) {
      hint = ctx.newt[0];
    } else if (st == I2M_DT_DUPLICATE) {
      ndup++;
    } else {
      err = I2M_ERROR(st == I2M_DT_FULL ? I2M_ERR_MEMORY : I2M_ERR_INTERNAL,
                      "inserting point %u failed (status %d)", k, (int)st);
      break;
    }
    if (vid_out) vid_out[k] = v;
  }
  i2m_debug("bulk insertion: %lld points, %.2f tets created and %.2f killed per point, %.2f walk steps per point",
            (long long)ctx.n_insert, (double)ctx.n_created / (double)(ctx.n_insert + 1),
            (double)ctx.n_killed / (double)(ctx.n_insert + 1), (double)ctx.n_walk_steps / (double)(ctx.n_insert + 1));
  i2m_dt_ctx_flush(&ctx);
  i2m_dt_ctx_free(&ctx);
  if (nduplicates) *nduplicates = ndup;
done:
  i2m_free(&order);
  return err;
}
