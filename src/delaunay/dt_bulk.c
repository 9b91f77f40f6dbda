/* Delaunay layer: bulk insertion of a point set in BRIO order (biased randomized insertion
 * order: random rounds of geometrically growing size), each round sorted along a Hilbert
 * curve, every point located by a visibility walk from the previous insertion. */
#include "dt_impl.h"

#include <math.h>
#include <stdlib.h>

#define HILBERT_BITS 16

/* Hilbert index of a point with HILBERT_BITS-bit integer coordinates, after Skilling's
 * transpose formulation ("Programming the Hilbert curve", 2004): undo the excess work of
 * the rotations from the top bit down, Gray-encode, then interleave the bits. */
static uint64_t hilbert_key(uint32_t X[3])
{
  const uint32_t M = 1u << (HILBERT_BITS - 1);
  for (uint32_t Q = M; Q > 1; Q >>= 1) {
    uint32_t P = Q - 1;
    for (int i = 0; i < 3; i++) {
      if (X[i] & Q) {
        X[0] ^= P; /* invert the low bits of axis 0 */
      } else {       /* exchange the low bits of axes 0 and i */
        uint32_t t = (X[0] ^ X[i]) & P;
        X[0] ^= t;
        X[i] ^= t;
      }
    }
  }
  X[1] ^= X[0];
  X[2] ^= X[1];
  uint32_t t = 0;
  for (uint32_t Q = M; Q > 1; Q >>= 1)
    if (X[2] & Q) t ^= Q - 1;
  for (int i = 0; i < 3; i++) X[i] ^= t;
  uint64_t key = 0;
  for (int b = HILBERT_BITS - 1; b >= 0; b--)
    for (int i = 0; i < 3; i++) key = (key << 1) | ((X[i] >> b) & 1u);
  return key;
}

static uint64_t splitmix(uint64_t *s)
{
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/* LSD radix sort of (key, index) pairs on the low @p bits bits of key, 16 bits a pass. */
static i2m_err_t radix_sort(uint64_t *key, uint32_t *idx, size_t n, int bits)
{
  uint64_t *k2 = NULL;
  uint32_t *i2 = NULL;
  size_t *count = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *k2, &k2));
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *i2, &i2));
  I2M_CALL_GOTO(err, done, i2m_malloc(65536, sizeof *count, &count));
  for (int shift = 0; shift < bits; shift += 16) {
    memset(count, 0, 65536 * sizeof *count);
    for (size_t i = 0; i < n; i++) count[(key[i] >> shift) & 0xFFFF]++;
    size_t sum = 0;
    for (size_t d = 0; d < 65536; d++) {
      size_t c = count[d];
      count[d] = sum;
      sum += c;
    }
    for (size_t i = 0; i < n; i++) {
      size_t dst = count[(key[i] >> shift) & 0xFFFF]++;
      k2[dst] = key[i];
      i2[dst] = idx[i];
    }
    memcpy(key, k2, n * sizeof *key);
    memcpy(idx, i2, n * sizeof *idx);
  }
done:
  i2m_free(&k2);
  i2m_free(&i2);
  i2m_free(&count);
  return err;
}

/* Insertion order: a random permutation cut into rounds (the last holds ~87% of the points,
 * each earlier one 7.5 times fewer, the first at most 2048), each round in Hilbert order. */
static i2m_err_t brio_order(const double *xyz, size_t n, uint64_t seed, uint32_t **order_out)
{
  uint32_t *order = NULL;
  uint64_t *key = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *order, &order));
  I2M_CALL_GOTO(err, done, i2m_malloc(n, sizeof *key, &key));
  for (size_t i = 0; i < n; i++) order[i] = (uint32_t)i;
  uint64_t s = seed;
  for (size_t i = n; i > 1; i--) { /* Fisher–Yates */
    size_t j = (size_t)(splitmix(&s) % i);
    uint32_t t = order[i - 1];
    order[i - 1] = order[j];
    order[j] = t;
  }
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < n; i++)
    for (int a = 0; a < 3; a++) {
      lo[a] = fmin(lo[a], xyz[3 * i + a]);
      hi[a] = fmax(hi[a], xyz[3 * i + a]);
    }
  double scale = 0;
  for (int a = 0; a < 3; a++) scale = fmax(scale, hi[a] - lo[a]);
  scale = scale > 0 ? ((1u << HILBERT_BITS) - 1) / scale : 0;
  /* round of position r in the shuffled order */
  size_t bound[64];
  int nr = 0;
  for (size_t end = n; end > 0 && nr < 63;) {
    bound[nr++] = end;
    size_t start = (size_t)((double)end / 7.5);
    if (start < 2048) break;
    end = start;
  }
  for (size_t r = 0; r < n; r++) {
    int round = 0; /* rounds counted from the first (smallest) */
    for (int b = nr - 1; b >= 0; b--)
      if (r < bound[b]) { round = nr - 1 - b; break; }
    const double *p = xyz + 3 * (size_t)order[r];
    uint32_t X[3];
    for (int a = 0; a < 3; a++) X[a] = (uint32_t)((p[a] - lo[a]) * scale);
    key[r] = ((uint64_t)round << 48) | hilbert_key(X);
  }
  I2M_CALL_GOTO(err, done, radix_sort(key, order, n, 64));
  *order_out = order;
  order = NULL;
done:
  i2m_free(&order);
  i2m_free(&key);
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
  I2M_CALL(brio_order(xyz, (size_t)n, seed, &order));
  I2M_CALL_GOTO(err, done, i2m_dt_ctx_init(&ctx, dt, 1, false));
  uint32_t hint = 0;
  while (!i2m_dt_alive(dt, hint)) hint++;
  for (int64_t r = 0; r < n; r++) {
    uint32_t k = order[r], v = I2M_DT_NONE;
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
