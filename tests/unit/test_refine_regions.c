/* Unit tests of regions.c: does a local change keep each label's connections?
 *   - region_keeps on regions written by hand (ports joined, cut, or left alone; portless
 *     pieces);
 *   - on a real triangulation whose tets carry labels that make thin, winding pieces: for
 *     each of 300 random insertions, the region of its cavity before and of its new tets
 *     after.  Whenever region_keeps says the change keeps the connections, the number of
 *     pieces of the whole mesh (face-connected tets of one label other than 0, counted by
 *     brute force) must not grow; the test also asserts that changes are refused and that
 *     some of the refused ones did cut a piece (so that the test can tell). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../../src/refine/refine_impl.h"
#include "test_util.h"

static region_port_t port(uint32_t a, uint32_t b, uint32_t c, uint32_t piece)
{
  return (region_port_t){{a, b, c}, piece, 0, false};
}

/* A region of ports by hand (their `shared` flags set as region_of_tets sets them). */
static region_t by_hand(region_port_t *p, uint32_t n, uint32_t nnodes, uint32_t portless)
{
  for (uint32_t i = 0; i < n; i++)
    for (uint32_t j = 0; j < n; j++) p[i].shared |= i != j && p[i].piece == p[j].piece;
  return (region_t){p, n, n, nnodes, portless};
}

static bool keeps(const region_t *before, const region_t *after)
{
  region_scratch_t S;
  memset(&S, 0, sizeof S);
  bool k = false;
  CU_ASSERT_EQUAL_FATAL(region_keeps(&S, NULL, before, after, &k), I2M_OK);
  region_scratch_free(&S);
  return k;
}

static void test_by_hand(void)
{
  /* before: one piece (node 1) with ports A = {0,2,3} and B = {2,3,4}, one (node 3) with C */
  region_port_t b[3] = {port(0, 2, 3, 1), port(2, 3, 4, 1), port(5, 6, 7, 3)};
  const region_t before = by_hand(b, 3, 4, 0);
  region_port_t a[3];
  a[0] = port(0, 2, 3, 0), a[1] = port(2, 3, 4, 0), a[2] = port(5, 6, 7, 2);
  region_t after = by_hand(a, 3, 3, 0);
  CU_ASSERT_TRUE(keeps(&before, &after));
  a[0] = port(0, 2, 3, 0), a[1] = port(2, 3, 4, 2); /* A and B in two pieces now: cut */
  after = by_hand(a, 2, 3, 0);
  CU_ASSERT_FALSE(keeps(&before, &after));
  a[0] = port(2, 3, 4, 0); /* A no port any more: cut */
  after = by_hand(a, 1, 3, 0);
  CU_ASSERT_FALSE(keeps(&before, &after));
  a[0] = port(0, 2, 3, 0), a[1] = port(2, 3, 4, 0); /* C's piece had one port: it may go */
  after = by_hand(a, 2, 3, 0);
  CU_ASSERT_TRUE(keeps(&before, &after));
  after = by_hand(a, 2, 3, 1); /* a new piece touching nothing of its label outside */
  CU_ASSERT_FALSE(keeps(&before, &after));
  const region_t lone = by_hand(b, 3, 4, 1); /* ... unless there was one before */
  CU_ASSERT_TRUE(keeps(&lone, &after));
}

/* ---- a labelled triangulation ---- */

static uint64_t rng = 88172645463325252ull;
static double urand(void)
{
  rng ^= rng << 13;
  rng ^= rng >> 7;
  rng ^= rng << 17;
  return (double)(rng >> 11) * 0x1.0p-53;
}

/* Label of tet t from its centroid: thin slabs and rods of three labels, 0 near the box. */
static uint16_t label_of(const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  double c[3] = {0, 0, 0};
  for (int i = 0; i < 4; i++) {
    if (v[i] < 8) return 0; /* (a box corner) */
    for (int a = 0; a < 3; a++) c[a] += 0.25 * i2m_dt_xyz(dt, v[i])[a];
  }
  const int s = (int)floor(c[0] * 7) + 2 * (int)floor(c[1] * 5) + (int)floor(c[2] * 3);
  return (uint16_t)(1 + (s % 3 + 3) % 3);
}

static uint32_t find(uint32_t *p, uint32_t x)
{
  while (p[x] != x) x = p[x] = p[p[x]];
  return x;
}

/* The pieces of the whole mesh, by brute force. */
static int64_t pieces(const i2m_dt_t *dt)
{
  const uint32_t n = i2m_dt_ntets_slots(dt);
  uint32_t *p = malloc(n * sizeof *p);
  for (uint32_t t = 0; t < n; t++) p[t] = t;
  for (uint32_t t = 0; t < n; t++) {
    if (!i2m_dt_alive(dt, t) || tinfo(dt, t)->label == 0) continue;
    for (int j = 0; j < 4; j++) {
      const uint32_t nb = dt->tn[4 * (size_t)t + j];
      if (nb >= I2M_DT_REMOTE || tinfo(dt, nb >> 2)->label != tinfo(dt, t)->label) continue;
      const uint32_t a = find(p, t), b = find(p, nb >> 2);
      if (a != b) p[a] = b;
    }
  }
  int64_t k = 0;
  for (uint32_t t = 0; t < n; t++) k += i2m_dt_alive(dt, t) && tinfo(dt, t)->label != 0 && find(p, t) == t;
  free(p);
  return k;
}

typedef struct {
  region_scratch_t *S;
  region_t *before;
} hook_t;

static bool region_hook(void *arg, const i2m_dt_ctx_t *ctx, const double p[3])
{
  (void)p;
  hook_t *h = arg;
  return region_of_tets(h->S, ctx->dt, ctx->cav, ctx->ncav, -1, h->before) == I2M_OK;
}

static void test_insertions(void)
{
  const size_t n = 3000;
  double *xyz = malloc(3 * n * sizeof *xyz);
  for (size_t i = 0; i < 3 * n; i++) xyz[i] = urand();
  const double L[3] = {-8, -8, -8}, H[3] = {9, 9, 9};
  i2m_dt_t *dt = NULL;
  CU_ASSERT_FATAL(i2m_dt_create(L, H, (uint32_t)n + 400, sizeof(tet_info_t), &dt) == I2M_OK);
  uint32_t *vid = malloc(n * sizeof *vid);
  CU_ASSERT_FATAL(i2m_dt_insert_points(dt, xyz, (int64_t)n, 8, 5, vid, NULL) == I2M_OK);
  for (uint32_t t = 0; t < i2m_dt_ntets_slots(dt); t++)
    if (i2m_dt_alive(dt, t)) tinfo(dt, t)->label = label_of(dt, t);
  i2m_dt_ctx_t ctx;
  CU_ASSERT_FATAL(i2m_dt_ctx_init(&ctx, dt, 1, false) == I2M_OK);
  region_scratch_t S;
  memset(&S, 0, sizeof S);
  region_t before, after;
  memset(&before, 0, sizeof before);
  memset(&after, 0, sizeof after);
  hook_t h = {&S, &before};
  ctx.accept = region_hook;
  ctx.accept_arg = &h;
  int kept = 0, refused = 0, refused_cut = 0;
  int64_t now = pieces(dt);
  for (int m = 0; m < 300; m++) {
    double p[3] = {urand(), urand(), urand()};
    uint32_t v;
    const i2m_dt_status_t st = i2m_dt_insert_walk(&ctx, p, (int64_t)(n + 8 + (size_t)m), I2M_VK_FREE, dt->vtet[vid[0]], &v);
    i2m_dt_unlock_all(&ctx);
    CU_ASSERT_EQUAL_FATAL(st, I2M_DT_OK);
    for (uint32_t k = 0; k < ctx.nnew; k++) tinfo(dt, ctx.newt[k])->label = label_of(dt, ctx.newt[k]);
    CU_ASSERT_EQUAL_FATAL(region_of_tets(&S, dt, ctx.newt, ctx.nnew, -1, &after), I2M_OK);
    bool k = false;
    CU_ASSERT_EQUAL_FATAL(region_keeps(&S, dt, &before, &after, &k), I2M_OK);
    const int64_t next = pieces(dt);
    if (k) {
      CU_ASSERT(next <= now); /* kept: no piece cut anywhere */
      kept++;
    } else {
      refused++;
      refused_cut += next > now;
    }
    now = next;
  }
  CU_ASSERT(kept > 30 && refused > 30 && refused_cut > 5);
  region_free(&before);
  region_free(&after);
  region_scratch_free(&S);
  i2m_dt_ctx_free(&ctx);
  i2m_dt_destroy(&dt);
  free(vid);
  free(xyz);
}

static const test_case_t cases[] = {
    {"regions by hand", test_by_hand},
    {"insertions into a labelled mesh", test_insertions},
};

TEST_MAIN("refine regions", cases)
