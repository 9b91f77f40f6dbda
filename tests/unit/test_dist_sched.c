/* Unit tests of rank 0's task scheduler (src/dist/sched.c, dist layer internals, no MPI).
 *
 * The scheduler is pure bookkeeping, so whole runs are simulated here without MPI: a grid of
 * octree cells with random work, P = 1..5 "ranks" that ask for tasks in random order
 * (asynchronous mode) and report them done in random order, with new figures for their
 * blocks' cells (less work at the task's cell, now and then some more at a neighbour or for a
 * wide task, within a budget so that the run ends).  At every step, checked against a model
 * kept here from first principles: tasks in flight never have overlapping blocks (normal
 * block: the cell +-1 cell, wide: +-2, clipped; so centres are at least 3, 4 or 5 cells apart
 * along some axis), a task always has work, a request that gets nothing could get nothing,
 * the Location array gives a task's block to the rank that got it, the locks and counters
 * match, and sched_busy is false exactly when no cell has work and nothing is in flight;
 * at the end every cell that had work has run.  The deterministic mode's phases (one colour
 * of cells modulo 3, each task owned by the rank that holds most of its block, blocks never
 * overlapping; bridge points first; then the wide pass) are simulated the same way.  Also:
 * the blocks' clipping at the grid's faces and corners, the Morton partition (contiguous
 * shares, every rank some cells, tets balanced), the wide list. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../../src/dist/sched.h"
#include "test_util.h"

/* ---- a seeded generator (splitmix64) ---- */

static uint64_t rnd(uint64_t *s)
{
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/* A number in [0, n). */
static uint32_t below(uint64_t *s, uint32_t n) { return n ? (uint32_t)(rnd(s) % n) : 0; }

/* ---- the grid, from first principles ---- */

static void xyz(const int32_t n[3], uint32_t c, int32_t x[3])
{
  x[0] = (int32_t)(c % (uint32_t)n[0]);
  x[1] = (int32_t)(c / (uint32_t)n[0] % (uint32_t)n[1]);
  x[2] = (int32_t)(c / ((uint32_t)n[0] * (uint32_t)n[1]));
}

/* The largest coordinate difference of two cells. */
static int32_t cheb(const int32_t n[3], uint32_t a, uint32_t b)
{
  int32_t x[3], y[3], d = 0;
  xyz(n, a, x);
  xyz(n, b, y);
  for (int k = 0; k < 3; k++) {
    const int32_t e = x[k] > y[k] ? x[k] - y[k] : y[k] - x[k];
    d = e > d ? e : d;
  }
  return d;
}

static int radius(bool wide) { return wide ? 2 : 1; }

/* Is cell c in the block of task t? */
static bool in_block(const int32_t n[3], sched_task_t t, uint32_t c) { return cheb(n, t.cell, c) <= radius(t.wide); }

/* The cells of t's block, enumerated from its coordinates; returns their number. */
static uint32_t model_block(const int32_t n[3], sched_task_t t, uint32_t *cells)
{
  int32_t x[3], lo[3], hi[3];
  xyz(n, t.cell, x);
  for (int a = 0; a < 3; a++) {
    lo[a] = x[a] - radius(t.wide) > 0 ? x[a] - radius(t.wide) : 0;
    hi[a] = x[a] + radius(t.wide) < n[a] - 1 ? x[a] + radius(t.wide) : n[a] - 1;
  }
  uint32_t m = 0;
  for (int32_t k = lo[2]; k <= hi[2]; k++)
    for (int32_t j = lo[1]; j <= hi[1]; j++)
      for (int32_t i = lo[0]; i <= hi[0]; i++) cells[m++] = (uint32_t)((k * n[1] + j) * n[0] + i);
  return m;
}

/* Do the blocks of two tasks overlap (centres closer than their radii allow)? */
static bool overlap(const int32_t n[3], sched_task_t a, sched_task_t b)
{
  return cheb(n, a.cell, b.cell) <= radius(a.wide) + radius(b.wide);
}

static int colour_of(const int32_t n[3], uint32_t c)
{
  int32_t x[3];
  xyz(n, c, x);
  return x[0] % 3 + 3 * (x[1] % 3) + 9 * (x[2] % 3);
}

static uint64_t morton_key(const int32_t n[3], uint32_t c)
{
  int32_t x[3];
  xyz(n, c, x);
  uint64_t key = 0;
  for (int b = 0; b < 16; b++)
    for (int a = 0; a < 3; a++) key |= (uint64_t)((x[a] >> b) & 1) << (3 * b + a);
  return key;
}

/* ---- sched_block ---- */

static void check_block_grid(const int32_t n[3])
{
  sched_t S;
  CU_ASSERT_FATAL(sched_init(&S, n, 1) == I2M_OK);
  uint32_t cells[125];
  for (uint32_t c = 0; c < S.ncells; c++)
    for (int w = 0; w < 2; w++) {
      const sched_task_t t = {c, w != 0, 0};
      const uint32_t m = sched_block(&S, t, cells);
      int32_t x[3];
      xyz(n, c, x);
      uint32_t expect = 1;
      for (int a = 0; a < 3; a++) { /* the clipped extent along each axis */
        const int32_t lo = x[a] - radius(t.wide) < 0 ? 0 : x[a] - radius(t.wide);
        const int32_t hi = x[a] + radius(t.wide) > n[a] - 1 ? n[a] - 1 : x[a] + radius(t.wide);
        expect *= (uint32_t)(hi - lo + 1);
      }
      CU_ASSERT_EQUAL(m, expect);
      uint32_t inside = 0;
      for (uint32_t i = 0; i < m; i++) {
        CU_ASSERT(cells[i] < S.ncells);
        CU_ASSERT(cells[i] < S.ncells && in_block(n, t, cells[i]));
        for (uint32_t j = 0; j < i; j++) CU_ASSERT(cells[j] != cells[i]); /* each once */
        inside += cells[i] == c;
      }
      CU_ASSERT_EQUAL(inside, 1);
    }
  sched_free(&S);
}

static void test_block_clipping(void)
{
  static const int32_t grids[][3] = {{8, 8, 8}, {6, 4, 5}, {1, 1, 1}, {2, 3, 1}, {5, 1, 7}, {3, 3, 3}};
  for (size_t g = 0; g < sizeof grids / sizeof *grids; g++) check_block_grid(grids[g]);
  /* the corners and a few cells by hand */
  sched_t S;
  const int32_t n8[3] = {8, 8, 8}, n6[3] = {6, 4, 5};
  uint32_t cells[125];
  CU_ASSERT_FATAL(sched_init(&S, n8, 2) == I2M_OK);
  for (int i = 0; i < 8; i++) { /* the eight corners */
    const uint32_t c = (uint32_t)((i & 1) * 7 + ((i >> 1) & 1) * 56 + ((i >> 2) & 1) * 448);
    CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){c, false, 0}, cells), 8);
    CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){c, true, 0}, cells), 27);
  }
  CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){3 + 8 * 3 + 64 * 3, false, 0}, cells), 27);
  CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){3 + 8 * 3 + 64 * 3, true, 0}, cells), 125);
  CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){1 + 8 * 0 + 64 * 7, true, 0}, cells), 4 * 3 * 3); /* on an edge */
  sched_free(&S);
  CU_ASSERT_FATAL(sched_init(&S, n6, 3) == I2M_OK);
  CU_ASSERT_EQUAL(S.ncells, 120);
  CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){119, false, 0}, cells), 8); /* (5,3,4) */
  CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){119, true, 0}, cells), 27);
  CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){2 + 6 * 1 + 24 * 2, true, 0}, cells), 5 * 4 * 5); /* (2,1,2) */
  CU_ASSERT_EQUAL(sched_block(&S, (sched_task_t){2 + 6 * 1 + 24 * 2, false, 0}, cells), 27);
  sched_free(&S);
}

/* ---- sched_partition ---- */

typedef struct {
  uint64_t key;
  uint32_t cell;
} keyed_t;

static int cmp_keyed(const void *a, const void *b)
{
  const keyed_t *x = a, *y = b;
  return (x->key > y->key) - (x->key < y->key);
}

/* kind 0: no tets; 1: uniform random; 2: a few heavy cells among light ones.  Returns the
 * number of ranks without any cell. */
static int check_partition(const int32_t n[3], int P, int kind, uint64_t seed, bool verbose)
{
  sched_t S;
  CU_ASSERT_FATAL(sched_init(&S, n, P) == I2M_OK);
  int64_t total = 0, wmax = 0;
  for (uint32_t c = 0; c < S.ncells; c++) {
    S.tets[c] = kind == 0 ? 0 : kind == 1 ? below(&seed, 1000) : below(&seed, 20) == 0 ? 5000 + below(&seed, 5000) : below(&seed, 50);
    total += S.tets[c] + 1;
    wmax = S.tets[c] + 1 > wmax ? S.tets[c] + 1 : wmax;
  }
  sched_partition(&S);
  keyed_t *order = malloc(S.ncells * sizeof *order);
  int64_t *share = calloc((size_t)P, sizeof *share);
  uint32_t *count = calloc((size_t)P, sizeof *count);
  CU_ASSERT_FATAL(order && share && count);
  for (uint32_t c = 0; c < S.ncells; c++) order[c] = (keyed_t){morton_key(n, c), c};
  qsort(order, S.ncells, sizeof *order, cmp_keyed);
  int prev = 0;
  bool contiguous = true, in_range = true;
  for (uint32_t i = 0; i < S.ncells; i++) {
    const int h = S.home[order[i].cell];
    in_range &= h >= 0 && h < P;
    if (h < 0 || h >= P) continue;
    contiguous &= h >= prev; /* along the curve the shares come one after the other */
    prev = h;
    share[h] += S.tets[order[i].cell] + 1;
    count[h]++;
  }
  CU_ASSERT(in_range);
  CU_ASSERT(contiguous);
  int empty = 0;
  for (int q = 0; q < P; q++) {
    empty += count[q] == 0;
    if (verbose && count[q] == 0) {
      fprintf(stderr, "grid %dx%dx%d, %d ranks: rank %d has no cell; tets along the curve -> home:", n[0], n[1], n[2], P, q);
      for (uint32_t i = 0; i < S.ncells; i++)
        fprintf(stderr, " %lld->%d", (long long)S.tets[order[i].cell], S.home[order[i].cell]);
      fprintf(stderr, "\n");
    }
    /* a share is the cells whose middle falls in its 1/P of the curve: within one cell of it */
    const double ideal = (double)total / P;
    CU_ASSERT((double)share[q] <= ideal + (double)wmax + 1);
    if (count[q] > 0) CU_ASSERT((double)share[q] >= ideal - (double)wmax - 1);
    if (kind == 1 && S.ncells >= 64) CU_ASSERT((double)share[q] <= 1.25 * ideal && (double)share[q] >= 0.75 * ideal);
    if (kind == 0 && S.ncells >= (uint32_t)P) /* equal cells: counts differ by at most one */
      CU_ASSERT(count[q] + 1 >= S.ncells / (uint32_t)P && count[q] <= S.ncells / (uint32_t)P + 1);
  }
  free(order);
  free(share);
  free(count);
  sched_free(&S);
  return empty;
}

static const int32_t part_grids[][3] = {{8, 8, 8}, {6, 4, 5}, {2, 2, 2}, {5, 1, 1}, {4, 4, 4}, {7, 3, 2}};

static void test_partition(void)
{
  for (size_t g = 0; g < sizeof part_grids / sizeof *part_grids; g++)
    for (int P = 1; P <= 5; P++)
      for (int kind = 0; kind < 3; kind++)
        for (uint64_t seed = 1; seed <= 3; seed++) (void)check_partition(part_grids[g], P, kind, seed * 7919 + (uint64_t)P, false);
}

/* With at least as many cells as ranks, and tets that differ but not wildly, every rank gets
 * a share (a rank without one never gets a deterministic task: those go to the holders). */
static void test_partition_nonempty(void)
{
  for (size_t g = 0; g < sizeof part_grids / sizeof *part_grids; g++)
    for (int P = 1; P <= 5; P++)
      for (int kind = 0; kind < 2; kind++)
        for (uint64_t seed = 1; seed <= 3; seed++) {
          const int32_t *n = part_grids[g];
          if ((uint32_t)(n[0] * n[1] * n[2]) < (uint32_t)P) continue;
          CU_ASSERT_EQUAL(check_partition(n, P, kind, seed * 7919 + (uint64_t)P, true), 0);
        }
}

/* ---- the asynchronous mode, simulated ---- */

#define MAX_BATCH 6  /* tasks a request asks for at most */
#define MAX_TASKS 64 /* tasks of one feedback (a deterministic phase's, per rank) */
#define MAX_FLIGHT 64

typedef struct {
  int rank;
  uint32_t n;
  sched_task_t t[MAX_TASKS];
} batch_t;

typedef struct {
  sched_t S;
  int32_t n[3];
  int P;
  uint64_t rng;
  int64_t *work, *wide; /* [ncells] the model's figures */
  bool *pending;        /* [ncells] has had work since its last normal task */
  bool *pending_wide;   /* [ncells] has had wide work since its last wide task */
  batch_t fl[MAX_FLIGHT];
  uint32_t nfl;
  int64_t budget;       /* work that feedback may still add */
  bool points_round;    /* the deterministic mode's tasks insert bridge points only */
  int64_t given, wide_given;
  bool ok;
  char why[256];
} sim_t;

#define EXPECT(sim, cond, ...)                                        \
  do {                                                                \
    if (!(cond)) {                                                    \
      snprintf((sim)->why, sizeof (sim)->why, __VA_ARGS__);           \
      fprintf(stderr, "line %d: %s\n", __LINE__, (sim)->why);         \
      (sim)->ok = false;                                              \
      return false;                                                   \
    }                                                                 \
  } while (0)

static bool sim_init(sim_t *m, const int32_t n[3], int P, uint64_t seed, bool homes)
{
  memset(m, 0, sizeof *m);
  m->ok = true;
  m->P = P;
  m->rng = seed;
  for (int a = 0; a < 3; a++) m->n[a] = n[a];
  if (sched_init(&m->S, n, P) != I2M_OK) return false;
  const uint32_t nc = m->S.ncells;
  m->work = calloc(nc, sizeof *m->work);
  m->wide = calloc(nc, sizeof *m->wide);
  m->pending = calloc(nc, sizeof *m->pending);
  m->pending_wide = calloc(nc, sizeof *m->pending_wide);
  if (!m->work || !m->wide || !m->pending || !m->pending_wide) return false;
  for (uint32_t c = 0; c < nc; c++) {
    m->S.tets[c] = below(&m->rng, 3) ? below(&m->rng, 2000) : 0;
    m->work[c] = m->S.work[c] = below(&m->rng, 3) == 0 ? 1 + below(&m->rng, 12) : 0;
    m->wide[c] = m->S.wide[c] = below(&m->rng, 12) == 0 ? 1 + below(&m->rng, 3) : 0;
    m->pending[c] = m->work[c] > 0;
    m->pending_wide[c] = m->wide[c] > 0;
  }
  if (m->work[0] == 0) m->work[0] = m->S.work[0] = 1; /* (some work, even on a grid of one cell) */
  m->pending[0] = true;
  if (homes) { /* as after the coarse mesh's scatter; else rank 0 holds everything */
    sched_partition(&m->S);
    memcpy(m->S.holder, m->S.home, nc * sizeof *m->S.holder);
  }
  m->budget = nc / 2;
  return true;
}

static void sim_free(sim_t *m)
{
  sched_free(&m->S);
  free(m->work);
  free(m->wide);
  free(m->pending);
  free(m->pending_wide);
}

static bool model_busy(const sim_t *m)
{
  if (m->nfl) return true;
  for (uint32_t c = 0; c < m->S.ncells; c++)
    if (m->work[c] > 0 || m->wide[c] > 0) return true;
  return false;
}

/* Could task t run now, by the model (work, and no overlap with a task in flight)? */
static bool model_runnable(const sim_t *m, sched_task_t t)
{
  if ((t.wide ? m->wide[t.cell] : m->work[t.cell]) <= 0) return false;
  for (uint32_t b = 0; b < m->nfl; b++)
    for (uint32_t k = 0; k < m->fl[b].n; k++)
      if (overlap(m->n, t, m->fl[b].t[k])) return false;
  return true;
}

/* Tets of t's block a rank would fetch, by a Location array. */
static int64_t fetch_cost(const sim_t *m, const int32_t *holder, int rank, sched_task_t t)
{
  uint32_t cells[125];
  const uint32_t nb = model_block(m->n, t, cells);
  int64_t cost = 0;
  for (uint32_t i = 0; i < nb; i++)
    if (holder[cells[i]] != rank) cost += m->S.tets[cells[i]] + 1;
  return cost;
}

/* The scheduler's state against the model: figures, locks, tasks per rank, busy. */
static bool check_state(sim_t *m)
{
  const sched_t *S = &m->S;
  int32_t *per_rank = calloc((size_t)m->P, sizeof *per_rank);
  EXPECT(m, per_rank, "out of memory");
  for (uint32_t b = 0; b < m->nfl; b++) per_rank[m->fl[b].rank] += (int32_t)m->fl[b].n;
  bool same = true;
  for (int q = 0; q < m->P; q++) same &= S->inflight[q] == per_rank[q];
  free(per_rank);
  EXPECT(m, same, "tasks in flight per rank differ from the model's");
  for (uint32_t c = 0; c < S->ncells; c++) {
    EXPECT(m, S->work[c] == m->work[c] && S->wide[c] == m->wide[c], "cell %u: figures differ from the feedback", c);
    uint32_t locks = 0;
    for (uint32_t b = 0; b < m->nfl; b++)
      for (uint32_t k = 0; k < m->fl[b].n; k++) locks += in_block(m->n, m->fl[b].t[k], c);
    EXPECT(m, locks <= 1, "cell %u is in %u blocks in flight", c, locks);
    EXPECT(m, S->lock[c] == locks, "cell %u: lock %u, but %u tasks in flight hold it", c, S->lock[c], locks);
    for (int w = 0; w < 2; w++) {
      const sched_task_t t = {c, w != 0, 0};
      EXPECT(m, sched_runnable(S, t) == model_runnable(m, t), "cell %u%s: sched_runnable says %d", c, w ? " (wide)" : "",
             sched_runnable(S, t));
    }
  }
  EXPECT(m, sched_busy(S) == model_busy(m), "sched_busy is %d but the model says %d", sched_busy(S), model_busy(m));
  return true;
}

/* Every pair of tasks in flight: blocks apart (centres >= 3, 4 or 5 cells apart on an axis). */
static bool check_apart(sim_t *m)
{
  for (uint32_t b = 0; b < m->nfl; b++)
    for (uint32_t k = 0; k < m->fl[b].n; k++)
      for (uint32_t d = b; d < m->nfl; d++)
        for (uint32_t l = d == b ? k + 1 : 0; l < m->fl[d].n; l++) {
          const sched_task_t s = m->fl[b].t[k], t = m->fl[d].t[l];
          EXPECT(m, !overlap(m->n, s, t), "tasks at cells %u%s and %u%s (ranks %d, %d) in flight, %d cells apart", s.cell,
                 s.wide ? " (wide)" : "", t.cell, t.wide ? " (wide)" : "", m->fl[b].rank, m->fl[d].rank,
                 cheb(m->n, s.cell, t.cell));
        }
  return true;
}

/* The rank that holds most of task t's block (by tets; the lowest on a tie). */
static int model_best_rank(const sim_t *m, const int32_t *holder, sched_task_t t)
{
  uint32_t cells[125];
  const uint32_t nb = model_block(m->n, t, cells);
  int best = 0;
  int64_t most = -1;
  for (int q = 0; q < m->P; q++) {
    int64_t held = 0;
    for (uint32_t i = 0; i < nb; i++)
      if (holder[cells[i]] == q) held += m->S.tets[cells[i]] + 1;
    if (held > most) {
      most = held;
      best = q;
    }
  }
  return best;
}

/* Could rank q run a task, fetching within the cap? */
static bool model_rank_could_run(const sim_t *m, const int32_t *holder, int q, int64_t cap)
{
  int64_t held = 0;
  for (uint32_t c = 0; c < m->S.ncells; c++)
    if (holder[c] == q) held += m->S.tets[c] + 1;
  for (uint32_t c = 0; c < m->S.ncells; c++)
    for (int w = 0; w < 2; w++) {
      const sched_task_t t = {c, w != 0, 0};
      if (!model_runnable(m, t)) continue;
      const int64_t f = fetch_cost(m, holder, q, t);
      if (f == 0 || held + f <= cap) return true;
    }
  return false;
}

/* Could `rank` or another waiting rank run a task, fetching within the cap? */
static bool model_some_could_run(const sim_t *m, const int32_t *holder, int rank, int64_t cap)
{
  for (int q = 0; q < m->P; q++)
    if ((q == rank || m->S.waiting[q]) && model_rank_could_run(m, holder, q, cap)) return true;
  return false;
}

/* May `rank` fetch what task t needs (the bound on what a rank holds, SCHED_HOLD_SHARE times its
 * share, no busy rank, one neither waiting nor stopped, that holds at most SCHED_HOLD_SHARE
 * times its share, holds more of the block, and work worth the tets fetched,
 * SCHED_MOVE_WORTH; when nothing is in flight and every other rank waits, only the first,
 * and only while this or another waiting rank could run a task within it)? */
static bool model_may_fetch(const sim_t *m, const int32_t *holder, int rank, sched_task_t t)
{
  const int64_t f = fetch_cost(m, holder, rank, t);
  if (f == 0 || m->P == 1) return true;
  bool stalled = m->nfl == 0;
  for (int q = 0; q < m->P; q++) stalled &= q == rank || m->S.waiting[q] || m->S.done[q];
  const int b = model_best_rank(m, holder, t);
  int64_t held = 0, held_b = 0, total = 0;
  for (uint32_t c = 0; c < m->S.ncells; c++) {
    total += m->S.tets[c] + 1;
    if (holder[c] == rank) held += m->S.tets[c] + 1;
    if (holder[c] == b) held_b += m->S.tets[c] + 1;
  }
  const int64_t cap = (int64_t)((double)total * SCHED_HOLD_SHARE / m->P);
  if (stalled) return held + f <= cap || !model_some_could_run(m, holder, rank, cap);
  if (b != rank && !m->S.waiting[b] && !m->S.done[b] && (double)held_b * m->P <= (double)total * SCHED_HOLD_SHARE) return false;
  if ((double)(t.wide ? m->S.wide[t.cell] : m->S.work[t.cell]) * SCHED_MOVE_WORTH < (double)f) return false; /* (not worth it) */
  return held + f <= (int64_t)((double)total * SCHED_HOLD_SHARE / m->P);
}

/* What sched_pick gave `rank`, against the model and the Location before (saved). */
static bool check_pick(sim_t *m, int rank, uint32_t max, const sched_task_t *t, uint32_t n, const int32_t *saved)
{
  bool runnable_normal = false, runnable_wide = false;
  int64_t cheapest = INT64_MAX;
  for (uint32_t c = 0; c < m->S.ncells; c++) { /* (the model still has none of these tasks in flight) */
    const sched_task_t tn = {c, false, 0}, tw = {c, true, 0};
    if (model_runnable(m, tn) && model_may_fetch(m, saved, rank, tn)) {
      runnable_normal = true;
      const int64_t f = fetch_cost(m, saved, rank, tn);
      cheapest = f < cheapest ? f : cheapest;
    }
    runnable_wide |= model_runnable(m, tw) && model_may_fetch(m, saved, rank, tw);
  }
  EXPECT(m, n <= max, "%u tasks for a request of at most %u", n, max);
  EXPECT(m, n > 0 || (!runnable_normal && !runnable_wide), "rank %d got nothing though a task could run", rank);
  for (uint32_t k = 0; k < n; k++) {
    EXPECT(m, t[k].cell < m->S.ncells, "a task at cell %u of %u", t[k].cell, m->S.ncells);
    EXPECT(m, (t[k].wide ? m->wide[t[k].cell] : m->work[t[k].cell]) > 0, "a task at cell %u%s, which has no work",
           t[k].cell, t[k].wide ? " (wide)" : "");
    EXPECT(m, !t[k].wide || n == 1, "a wide task in a batch of %u", n);
    EXPECT(m, !t[k].wide || !runnable_normal, "a wide task while a normal one could run");
    EXPECT(m, model_may_fetch(m, saved, rank, t[k]), "rank %d fetches more than the bound on what it holds", rank);
    EXPECT(m, model_runnable(m, t[k]), "cell %u: its block overlaps a task in flight", t[k].cell);
    for (uint32_t l = 0; l < k; l++) EXPECT(m, !overlap(m->n, t[k], t[l]), "one batch: cells %u and %u overlap", t[k].cell, t[l].cell);
    if (k == 0 && !t[0].wide) /* the block the rank holds most of first */
      EXPECT(m, fetch_cost(m, saved, rank, t[0]) == cheapest, "rank %d's first task fetches %lld tets, %lld would do", rank,
             (long long)fetch_cost(m, saved, rank, t[0]), (long long)cheapest);
    if (k > 0) EXPECT(m, fetch_cost(m, saved, rank, t[k]) == 0, "task %u of a batch fetches data", k);
  }
  for (uint32_t c = 0; c < m->S.ncells; c++) { /* the Location array: the blocks now the rank's, the rest unchanged */
    bool mine = false;
    for (uint32_t k = 0; k < n; k++) mine |= in_block(m->n, t[k], c);
    EXPECT(m, m->S.holder[c] == (mine ? rank : saved[c]), "cell %u held by %d, expected %d", c, m->S.holder[c],
           mine ? rank : saved[c]);
  }
  return true;
}

static bool sim_request(sim_t *m, int rank)
{
  const uint32_t max = 1 + below(&m->rng, MAX_BATCH);
  sched_task_t t[MAX_BATCH];
  int32_t *saved = malloc(m->S.ncells * sizeof *saved);
  EXPECT(m, saved, "out of memory");
  memcpy(saved, m->S.holder, m->S.ncells * sizeof *saved);
  const uint32_t n = sched_pick(&m->S, rank, max, t);
  const bool good = check_pick(m, rank, max, t, n, saved);
  free(saved);
  if (!good) return false;
  m->S.waiting[rank] = n == 0; /* (the engine's waiting list) */
  if (n == 0) return true;
  batch_t *b = &m->fl[m->nfl++];
  b->rank = rank;
  b->n = n;
  for (uint32_t k = 0; k < n; k++) {
    b->t[k] = t[k];
    if (t[k].wide) m->pending_wide[t[k].cell] = false;
    else m->pending[t[k].cell] = false;
    m->given++;
    m->wide_given += t[k].wide;
  }
  return true;
}

/* New figures of one cell of a finished task's block. */
static sched_cell_t new_figures(sim_t *m, uint32_t c, const batch_t *b)
{
  sched_cell_t f = {c, m->work[c], m->wide[c], below(&m->rng, 3000), m->S.points[c], m->S.wpoints[c], 0};
  bool centre = false;
  for (uint32_t k = 0; k < b->n; k++) {
    if (b->t[k].cell != c) continue;
    centre = true;
    if (!b->t[k].wide) f.points = 0; /* (its points are in) */
    if (m->points_round) continue;
    if (b->t[k].wide) f.wide = below(&m->rng, 2) ? 0 : below(&m->rng, (uint32_t)f.wide); /* less wide work */
    else f.work = below(&m->rng, 3) == 0 ? 0 : below(&m->rng, (uint32_t)f.work);     /* less work */
  }
  if (m->budget > 0 && below(&m->rng, centre ? 40 : 10) == 0) { /* work spills over to a neighbour */
    f.work += 1 + below(&m->rng, 3);
    m->budget--;
  }
  if (m->budget > 0 && below(&m->rng, 30) == 0) { /* an element that needs a wide task */
    f.wide += 1 + below(&m->rng, 2);
    m->budget--;
  }
  return f;
}

static bool sim_complete(sim_t *m, uint32_t which)
{
  const batch_t b = m->fl[which];
  m->fl[which] = m->fl[--m->nfl]; /* out of flight before the model's check */
  sched_cell_t *f = malloc(125 * MAX_TASKS * sizeof *f);
  EXPECT(m, f, "out of memory");
  uint32_t nf = 0;
  for (uint32_t c = 0; c < m->S.ncells; c++) {
    bool mine = false;
    for (uint32_t k = 0; k < b.n; k++) mine |= in_block(m->n, b.t[k], c);
    if (mine) f[nf++] = new_figures(m, c, &b);
  }
  for (uint32_t i = nf; i > 1; i--) { /* in a random order */
    const uint32_t j = below(&m->rng, i);
    const sched_cell_t x = f[i - 1];
    f[i - 1] = f[j];
    f[j] = x;
  }
  for (uint32_t i = 0; i < nf; i++) {
    const uint32_t c = f[i].cell;
    if (f[i].work > 0 && m->work[c] == 0) m->pending[c] = true;
    if (f[i].wide > 0 && m->wide[c] == 0) m->pending_wide[c] = true;
    m->work[c] = f[i].work;
    m->wide[c] = f[i].wide;
  }
  sched_feedback(&m->S, b.rank, b.t, b.n, f, nf);
  free(f);
  return true;
}

/* One run: requests and completions in random order until the scheduler says the end. */
static bool sim_async(const int32_t n[3], int P, uint64_t seed, bool homes, int64_t *tasks)
{
  sim_t m;
  bool ok = sim_init(&m, n, P, seed, homes);
  const int max_per_rank = 1 + (int)(seed % 2); /* (the engine keeps one batch per rank; two here too) */
  for (int64_t step = 0; ok && step < 1000000; step++) {
    ok = check_state(&m) && check_apart(&m);
    if (!ok || !sched_busy(&m.S)) break;
    int asking[8], na = 0;
    for (int q = 0; q < P; q++) {
      int mine = 0;
      for (uint32_t b = 0; b < m.nfl; b++) mine += m.fl[b].rank == q;
      if (mine < max_per_rank) asking[na++] = q;
    }
    if (na && (m.nfl == 0 || below(&m.rng, 2))) ok = sim_request(&m, asking[below(&m.rng, (uint32_t)na)]);
    else ok = sim_complete(&m, below(&m.rng, m.nfl));
  }
  if (ok) {
    ok = !sched_busy(&m.S) && !model_busy(&m);
    if (!ok) fprintf(stderr, "no end after a million steps\n");
  }
  for (uint32_t c = 0; ok && c < m.S.ncells; c++)
    if (m.pending[c] || m.pending_wide[c]) {
      fprintf(stderr, "cell %u had work but never ran\n", c);
      ok = false;
    }
  if (ok && (m.S.tasks_given != m.given || m.S.wide_given != m.wide_given)) {
    fprintf(stderr, "tasks given: %lld (%lld wide), counted %lld (%lld)\n", (long long)m.S.tasks_given,
            (long long)m.S.wide_given, (long long)m.given, (long long)m.wide_given);
    ok = false;
  }
  *tasks = m.given;
  sim_free(&m);
  return ok;
}

static void run_async(const int32_t n[3])
{
  for (int P = 1; P <= 5; P++)
    for (uint64_t seed = 1; seed <= 4; seed++) {
      int64_t tasks = 0;
      const bool ok = sim_async(n, P, seed * 1000003 + (uint64_t)P, seed % 2 == 1, &tasks);
      if (!ok) fprintf(stderr, "  grid %dx%dx%d, %d ranks, seed %llu\n", n[0], n[1], n[2], P, (unsigned long long)seed);
      CU_ASSERT(ok);
      CU_ASSERT(tasks > 0);
    }
}

static void test_async_cube(void) { run_async((const int32_t[3]){8, 8, 8}); }
static void test_async_box(void) { run_async((const int32_t[3]){6, 4, 5}); }
static void test_async_small(void)
{
  run_async((const int32_t[3]){3, 3, 3});
  run_async((const int32_t[3]){7, 1, 1});
  run_async((const int32_t[3]){1, 1, 1});
}

/* ---- the deterministic mode, simulated ---- */

/* The rank that holds most tets of t's block (+1 a cell) now; the lowest on a tie. */
static int model_best(const sim_t *m, sched_task_t t) { return model_best_rank(m, m->S.holder, t); }

/* The owners a deterministic phase should give (expect[c], -1 for the cells without a task),
 * from the Location before it: the tasks by work (most first, then by cell), each to the rank
 * that holds most of its block, unless that one would fetch and come to hold more than
 * SCHED_HOLD_SHARE times its share of the tets; then to the one that would hold least after it.  Counts in *redirected the tasks that went to another than the best. */
static uint32_t model_phase(sim_t *m, int colour, bool points_only, int *expect, int64_t *redirected)
{
  const sched_t *S = &m->S;
  const uint32_t nc = S->ncells;
  int32_t *hold = malloc(nc * sizeof *hold);
  uint32_t *order = malloc(nc * sizeof *order), n = 0;
  EXPECT(m, hold && order, "out of memory");
  memcpy(hold, S->holder, nc * sizeof *hold);
  for (uint32_t c = 0; c < nc; c++) {
    expect[c] = -1;
    const int64_t w = points_only ? S->points[c] : m->work[c];
    if (colour_of(m->n, c) != colour || w <= 0) continue;
    uint32_t k = n++; /* (insertion sort: most work first, then the lower cell) */
    for (; k > 0; k--) {
      const int64_t v = points_only ? S->points[order[k - 1]] : m->work[order[k - 1]];
      if (v >= w) break;
      order[k] = order[k - 1];
    }
    order[k] = c;
  }
  for (uint32_t i = 0; i < n; i++) {
    const sched_task_t t = {order[i], false, 0};
    int64_t total = 0;
    int64_t *held = calloc((size_t)m->P, sizeof *held);
    EXPECT(m, held, "out of memory");
    for (uint32_t c = 0; c < nc; c++) {
      total += S->tets[c] + 1;
      held[hold[c]] += S->tets[c] + 1;
    }
    const int best = model_best_rank(m, hold, t);
    int q = best;
    const int64_t f = fetch_cost(m, hold, best, t);
    if (f > 0 && (double)(held[best] + f) * m->P > (double)total * SCHED_HOLD_SHARE) {
      int64_t after = INT64_MAX, fq = INT64_MAX; /* the least held after it, then the least fetched, then the lowest */
      for (int r = 0; r < m->P; r++) {
        const int64_t fr = fetch_cost(m, hold, r, t);
        if (held[r] + fr < after || (held[r] + fr == after && fr < fq)) after = held[r] + fr, fq = fr, q = r;
      }
    }
    *redirected += q != best;
    expect[t.cell] = q;
    uint32_t cells[125];
    const uint32_t nb = model_block(m->n, t, cells);
    for (uint32_t j = 0; j < nb; j++) hold[cells[j]] = q;
    free(held);
  }
  free(hold);
  free(order);
  return n;
}

/* One phase: the tasks of a colour, checked, then every rank's feedback. */
static bool det_phase(sim_t *m, int colour, bool points_only, int64_t *redirected)
{
  sched_t *S = &m->S;
  const uint32_t nc = S->ncells;
  int *expect = malloc(nc * sizeof *expect), *owner = malloc(nc * sizeof *owner);
  sched_task_t *t = malloc(nc * sizeof *t);
  EXPECT(m, expect && owner && t, "out of memory");
  const uint32_t want = model_phase(m, colour, points_only, expect, redirected);
  const uint32_t n = sched_phase(S, colour, points_only, t, owner);
  EXPECT(m, n <= MAX_TASKS, "(a grid too large for this test: %u tasks in a phase)", n);
  EXPECT(m, n == want, "colour %d: %u tasks, %u cells of the colour have work", colour, n, want);
  for (uint32_t k = 0; k < n; k++) {
    const uint32_t c = t[k].cell;
    EXPECT(m, c < nc && !t[k].wide && colour_of(m->n, c) == colour, "colour %d: a task at cell %u (colour %d)", colour, c,
           colour_of(m->n, c));
    EXPECT(m, expect[c] >= 0, "colour %d: cell %u twice, or without work", colour, c);
    EXPECT(m, owner[k] == expect[c], "cell %u given to rank %d, the model's rank is %d", c, owner[k], expect[c]);
    expect[c] = -1;
    if (!points_only) m->pending[c] = false;
    for (uint32_t l = 0; l < k; l++) EXPECT(m, !overlap(m->n, t[k], t[l]), "colour %d: cells %u and %u overlap", colour, c, t[l].cell);
    for (uint32_t x = 0; x < nc; x++)
      if (in_block(m->n, t[k], x)) EXPECT(m, S->holder[x] == owner[k] && S->lock[x] == 1, "cell %u of cell %u's block", x, c);
  }
  for (int q = 0; q < m->P; q++) { /* the model's flight: each rank's tasks, one feedback each */
    batch_t *b = &m->fl[m->nfl++];
    b->rank = q;
    b->n = 0;
    for (uint32_t k = 0; k < n; k++)
      if (owner[k] == q && b->n < MAX_TASKS) b->t[b->n++] = t[k];
    if (b->n == 0) m->nfl--;
  }
  bool good = check_state(m) && check_apart(m);
  while (good && m->nfl) good = sim_complete(m, below(&m->rng, m->nfl)); /* in a random order */
  free(expect);
  free(owner);
  free(t);
  return good && check_state(m);
}

/* The wide pass: the wide list in order, one task at a time, to the rank that holds most. */
static bool det_wide(sim_t *m)
{
  uint32_t *list = malloc((m->S.ncells + 1) * sizeof *list);
  EXPECT(m, list, "out of memory");
  const uint32_t n = sched_wide_list(&m->S, false, list);
  uint32_t k = 0;
  bool good = true;
  for (uint32_t c = 0; c < m->S.ncells && good; c++) /* every cell with wide work, in order */
    if (m->wide[c] > 0) good = k < n && list[k++] == c;
  good &= k == n;
  if (!good) fprintf(stderr, "the wide list differs from the cells with wide work\n");
  for (uint32_t i = 0; i < n && good; i++) {
    if (m->wide[list[i]] <= 0) continue; /* (done by an earlier one) */
    const sched_task_t t = {list[i], true, 0};
    const int q = sched_best_rank(&m->S, t);
    good = q == model_best(m, t);
    sched_give(&m->S, q, t);
    m->pending_wide[t.cell] = false;
    for (uint32_t c = 0; c < m->S.ncells && good; c++)
      if (in_block(m->n, t, c)) good = m->S.holder[c] == q && m->S.lock[c] == 1;
    if (!good) fprintf(stderr, "wide task at cell %u: owner or block wrong\n", t.cell);
    m->fl[m->nfl++] = (batch_t){q, 1, {t}};
    good = good && sim_complete(m, m->nfl - 1) && check_state(m);
  }
  free(list);
  return good;
}

/* Bridge points on some cells with work (counted in it); the model's work covers them. */
static void add_points(sim_t *m)
{
  for (uint32_t c = 0; c < m->S.ncells; c++)
    if (m->work[c] > 0 && below(&m->rng, 4) == 0) m->S.points[c] = 1 + below(&m->rng, (uint32_t)m->work[c]);
}

static bool sim_det(const int32_t n[3], int P, uint64_t seed, int64_t *tasks, int64_t *redirected)
{
  sim_t m;
  bool ok = sim_init(&m, n, P, seed, true);
  if (ok) add_points(&m);
  int rounds = 0;
  while (ok && sched_busy(&m.S) && rounds++ < 10000) {
    const bool points = sched_has_points(&m.S);
    m.points_round = points;
    for (int colour = 0; colour < 27 && ok; colour++) {
      ok = det_phase(&m, colour, points, redirected);
      for (uint32_t c = 0; ok && points && c < m.S.ncells; c++)
        if (colour_of(n, c) == colour && m.S.points[c]) ok = false, fprintf(stderr, "cell %u: points left\n", c);
    }
    if (ok && !points) ok = det_wide(&m);
    if (ok) ok = check_state(&m);
  }
  ok = ok && !sched_busy(&m.S) && !model_busy(&m) && !sched_has_points(&m.S);
  for (uint32_t c = 0; ok && c < m.S.ncells; c++)
    if (m.pending[c] || m.pending_wide[c]) ok = false, fprintf(stderr, "cell %u had work but never ran\n", c);
  for (uint32_t c = 0; ok && c < m.S.ncells; c++) ok = m.S.lock[c] == 0;
  *tasks = m.S.tasks_given;
  sim_free(&m);
  return ok;
}

static void run_det(const int32_t n[3], int64_t *redirected)
{
  for (int P = 1; P <= 5; P++)
    for (uint64_t seed = 1; seed <= 3; seed++) {
      int64_t tasks = 0;
      const bool ok = sim_det(n, P, seed * 7777 + (uint64_t)P, &tasks, redirected);
      if (!ok) fprintf(stderr, "  deterministic: grid %dx%dx%d, %d ranks, seed %llu\n", n[0], n[1], n[2], P,
                       (unsigned long long)seed);
      CU_ASSERT(ok);
      CU_ASSERT(tasks > 0);
    }
}

static void test_det_phases(void)
{
  int64_t redirected = 0;
  run_det((const int32_t[3]){8, 8, 8}, &redirected);
  run_det((const int32_t[3]){6, 4, 5}, &redirected);
  run_det((const int32_t[3]){4, 2, 1}, &redirected);
  CU_ASSERT(redirected > 0); /* (the bound on what a rank holds did send tasks elsewhere) */
}

/* ---- small cases by hand ---- */

static void test_wide_list(void)
{
  const int32_t n[3] = {6, 4, 5};
  sched_t S;
  uint32_t list[121];
  CU_ASSERT_FATAL(sched_init(&S, n, 2) == I2M_OK);
  CU_ASSERT_EQUAL(sched_wide_list(&S, false, list), 0);
  S.wide[119] = 2;
  S.wide[0] = 1;
  S.wide[57] = 5;
  S.work[3] = 4;  /* normal work: not on the list */
  S.wide[8] = -1; /* (not a positive figure) */
  CU_ASSERT_EQUAL(sched_wide_list(&S, false, list), 3);
  CU_ASSERT(list[0] == 0 && list[1] == 57 && list[2] == 119);
  S.wpoints[57] = 2; /* right after the bridge points: only the wide tasks with points */
  CU_ASSERT_EQUAL(sched_wide_list(&S, true, list), 1);
  CU_ASSERT(list[0] == 57);
  for (uint32_t c = 0; c < S.ncells; c++) S.wide[c] = 1;
  CU_ASSERT_EQUAL(sched_wide_list(&S, false, list), 120);
  bool ordered = true;
  for (uint32_t i = 0; i < 120; i++) ordered &= list[i] == i;
  CU_ASSERT(ordered);
  sched_free(&S);
}

static void test_busy_by_hand(void)
{
  const int32_t n[3] = {8, 8, 8};
  sched_t S;
  sched_task_t t[4];
  CU_ASSERT_FATAL(sched_init(&S, n, 3) == I2M_OK);
  CU_ASSERT(!sched_busy(&S));
  CU_ASSERT_EQUAL(sched_pick(&S, 1, 4, t), 0); /* nothing to do */
  S.points[5] = 3;                             /* points alone are no work */
  CU_ASSERT(!sched_busy(&S) && sched_has_points(&S));
  S.points[5] = 0;
  S.wide[100] = 2; /* only wide work: one wide task, alone */
  CU_ASSERT(sched_busy(&S));
  S.done[0] = true; /* (rank 0, which holds every block, has stopped: the others may fetch) */
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 2, 4, t), 1);
  CU_ASSERT(t[0].cell == 100 && t[0].wide);
  CU_ASSERT(S.holder[100] == 2 && S.lock[100] == 1 && S.inflight[2] == 1);
  CU_ASSERT_EQUAL(sched_pick(&S, 1, 4, t), 0);
  S.work[100 + 3] = 1; /* three cells away from a wide task: its block overlaps, cannot run */
  CU_ASSERT(!sched_runnable(&S, (sched_task_t){103, false, 0}));
  CU_ASSERT_EQUAL(sched_pick(&S, 1, 4, t), 0);
  S.work[103] = 0;
  S.work[100 + 4] = 1; /* four: it can */
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 1, 4, t), 1);
  CU_ASSERT(t[0].cell == 104 && !t[0].wide);
  const sched_cell_t done_wide = {100, 0, 0, 10, 0, 0, 0}, done_104 = {104, 0, 0, 10, 0, 0, 0};
  const sched_task_t w = {100, true, 0}, x = {104, false, 0};
  sched_feedback(&S, 2, &w, 1, &done_wide, 1);
  CU_ASSERT(sched_busy(&S));
  S.work[104] = 0; /* (as if its figure had come from elsewhere) */
  CU_ASSERT(sched_busy(&S)); /* a task still in flight, though no work is left */
  sched_feedback(&S, 1, &x, 1, &done_104, 1);
  CU_ASSERT(!sched_busy(&S));
  for (uint32_t c = 0; c < S.ncells; c++) CU_ASSERT(S.lock[c] == 0);
  CU_ASSERT(S.inflight[0] == 0 && S.inflight[1] == 0 && S.inflight[2] == 0);
  CU_ASSERT(S.tasks_given == 2 && S.wide_given == 1);
  /* normal and wide work at once: the normal task first */
  S.wide[0] = 1;
  S.work[511] = 1;
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 0, 4, t), 1);
  CU_ASSERT(t[0].cell == 511 && !t[0].wide);
  sched_free(&S);
}

/* A scheduler over 8 x 8 x 8 cells for two ranks, each cell with `tets` tets. */
static void two_ranks_cube(sched_t *S, int64_t tets)
{
  const int32_t n[3] = {8, 8, 8};
  CU_ASSERT_FATAL(sched_init(S, n, 2) == I2M_OK);
  for (uint32_t c = 0; c < S->ncells; c++) S->tets[c] = tets;
}

/* As two_ranks_cube, the cells with x < 4 rank 0's, the others rank 1's. */
static void two_ranks_halves(sched_t *S, int64_t tets)
{
  two_ranks_cube(S, tets);
  for (uint32_t c = 0; c < S->ncells; c++) S->holder[c] = c % 8 < 4 ? 0 : 1;
}

/* A task fetches data only for work worth it (SCHED_MOVE_WORTH), unless the run would stall. */
static void test_move_worth(void)
{
  sched_t S;
  sched_task_t t[4];
  two_ranks_cube(&S, 1000);
  for (uint32_t c = 0; c < S.ncells; c++) /* rank 1 holds everything, and runs a task (no block locked here) */
    S.holder[c] = 1;
  S.inflight[1] = 1;
  const int64_t fetch = 8 * 1001; /* cell 0's block: the corner's 8 cells, each weighing one more */
  S.work[0] = (int64_t)ceil((double)fetch / SCHED_MOVE_WORTH) - 1;
  CU_ASSERT_EQUAL(sched_pick(&S, 0, 4, t), 0); /* too little work for its tets */
  S.work[0]++;
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 0, 4, t), 1); /* enough */
  CU_ASSERT(t[0].cell == 0 && S.holder[0] == 0 && S.holder[1] == 0 && S.holder[2] == 1);
  const sched_cell_t done0 = {0, 1, 0, 1000, 0, 0, 0};
  sched_feedback(&S, 0, t, 1, &done0, 1); /* one bad element left, rank 0 holds the block now */
  S.work[511] = 1;                        /* one at the far corner, which rank 1 holds */
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 0, 4, t), 1); /* its own first, fetching nothing */
  CU_ASSERT(t[0].cell == 0);
  sched_feedback(&S, 0, t, 1, &(sched_cell_t){0, 0, 0, 1000, 0, 0, 0}, 1);
  CU_ASSERT_EQUAL(sched_pick(&S, 0, 4, t), 0); /* cell 511's: not worth it while rank 1 works */
  S.inflight[1] = 0;
  S.waiting[1] = true; /* rank 1 waits and nothing is in flight: rank 0 fetches, or nobody would */
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 0, 4, t), 1);
  CU_ASSERT(t[0].cell == 511 && S.holder[511] == 0);
  sched_free(&S);
  /* a stall where the asking rank would hold over SCHED_HOLD_SHARE times its share: the waiting
   * one, which would not, gets the task */
  two_ranks_cube(&S, 1000);
  for (uint32_t c = 0; c < S.ncells; c++) /* rank 0: 400 cells of 1000 tets, above 1.3 / 2 of them all */
    S.holder[c] = c < 400 ? 0 : 1;
  const uint32_t across = (6 * 8 + 1) * 8 + 3; /* (3, 1, 6): its block has cells of both ranks */
  S.work[across] = 100000;
  S.waiting[1] = true;
  CU_ASSERT_EQUAL(sched_pick(&S, 0, 4, t), 0);
  CU_ASSERT(sched_other_could_run(&S, 0));
  S.waiting[0] = true;
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 1, 4, t), 1);
  CU_ASSERT(t[0].cell == across && S.holder[across] == 1);
  sched_free(&S);
}

/* sched_pick_held: only tasks whose whole block the rank holds, even on a stall (every other
 * rank waiting, nothing in flight), and sched_in_flight. */
static void test_pick_held(void)
{
  sched_t S;
  sched_task_t t[4];
  two_ranks_halves(&S, 100);
  const uint32_t inside = 1 + 8 * (3 + 8 * 3), border = 3 + 8 * (3 + 8 * 3); /* (x = 1 and x = 3) */
  S.work[border] = 50; /* the busiest, but its block reaches x = 4 */
  S.work[inside] = 1;
  S.waiting[1] = true; /* a stall: sched_pick would fetch */
  CU_ASSERT(!sched_in_flight(&S));
  CU_ASSERT_EQUAL_FATAL(sched_pick_held(&S, 0, 4, t), 1);
  CU_ASSERT(t[0].cell == inside && !t[0].wide);
  CU_ASSERT(sched_in_flight(&S));
  CU_ASSERT_EQUAL(sched_pick_held(&S, 0, 4, t), 0); /* the border task would fetch (and its block is locked) */
  sched_task_t done = {inside, false, 0};
  sched_feedback(&S, 0, &done, 1, NULL, 0);
  S.work[inside] = 0;
  CU_ASSERT(!sched_in_flight(&S));
  CU_ASSERT_EQUAL(sched_pick_held(&S, 0, 4, t), 0);
  CU_ASSERT_EQUAL(sched_pick_held(&S, 1, 4, t), 0);
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 0, 4, t), 1); /* (a stall: it may fetch) */
  CU_ASSERT(t[0].cell == border);
  sched_free(&S);
}

/* A task that skips sides of its cell: its fetch block is its block without the layers
 * beyond them; it fetches and takes only that, locks its whole block, and is priced by what it
 * fetches (a border cell whose elements lie away from the border runs without moving data). */
static void test_skip_sides(void)
{
  sched_t S;
  sched_task_t t[4];
  uint32_t cells[125];
  two_ranks_halves(&S, 1000);
  const uint32_t mid = 3 + 8 * (3 + 8 * 3); /* (3, 3, 3) */
  const unsigned no_x_hi = 1u << 1, only_x_hi = (1u << 6) - 1 - no_x_hi;
  CU_ASSERT_EQUAL(sched_fetch_block(&S, (sched_task_t){mid, false, 0}, cells), 27);
  CU_ASSERT_EQUAL(sched_fetch_block(&S, (sched_task_t){mid, false, no_x_hi}, cells), 18);
  CU_ASSERT_EQUAL_FATAL(sched_fetch_block(&S, (sched_task_t){mid, false, only_x_hi}, cells), 2);
  CU_ASSERT(cells[0] == mid && cells[1] == mid + 1);
  CU_ASSERT_EQUAL(sched_fetch_block(&S, (sched_task_t){mid, false, (1u << 6) - 1}, cells), 1);
  CU_ASSERT_EQUAL(sched_fetch_block(&S, (sched_task_t){mid, true, no_x_hi}, cells), 125); /* (wide: whole) */
  CU_ASSERT_EQUAL(sched_fetch_block(&S, (sched_task_t){0, false, no_x_hi}, cells), 4); /* (a corner, clipped) */
  S.inflight[1] = 1; /* rank 1 works: no stall */
  S.work[mid] = 1; /* one element: not worth the 9 cells across x = 4 */
  CU_ASSERT_EQUAL(sched_pick(&S, 0, 4, t), 0);
  S.skip[mid] = (uint8_t)no_x_hi; /* ... which it does not need */
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 0, 4, t), 1);
  CU_ASSERT(t[0].cell == mid && t[0].skip == no_x_hi && !t[0].wide);
  CU_ASSERT(S.lock[mid + 1] == 1 && S.holder[mid + 1] == 1); /* locked, not taken */
  sched_feedback(&S, 0, t, 1, &(sched_cell_t){mid, 0, 0, 1000, 0, 0, 0}, 1);
  CU_ASSERT(S.lock[mid + 1] == 0 && S.skip[mid] == 0);
  const uint32_t other = mid + 1; /* (4, 3, 3): rank 1's, its block reaches rank 0's x = 3 */
  S.work[other] = 100; /* (worth one cell's tets) */
  S.skip[other] = (uint8_t)(only_x_hi & ~1u & ~2u); /* (it needs both x sides: 3, rank 0's, and 5) */
  S.inflight[1] = 0;
  S.inflight[0] = 1;
  CU_ASSERT_EQUAL_FATAL(sched_pick(&S, 1, 4, t), 1);
  CU_ASSERT(t[0].cell == other && S.holder[other - 1] == 1 && S.holder[other - 1 + 8] == 0);
  CU_ASSERT(S.lock[other - 1 + 8] == 1 && S.lock[other - 2] == 0);
  sched_free(&S);
}

/* sched_pick_narrow: the tasks of the cells the rank holds, the busiest first, blocks apart and
 * locked, and no holder changes (nothing moves), even where the block reaches another rank's. */
static void test_pick_narrow(void)
{
  sched_t S;
  sched_task_t t[8];
  two_ranks_halves(&S, 100);
  int32_t before[512];
  memcpy(before, S.holder, sizeof before);
  const uint32_t border = 3 + 8 * (3 + 8 * 3), next = 2 + 8 * (3 + 8 * 3), far = 0 + 8 * (0 + 8 * 0);
  const uint32_t other = 4 + 8 * (3 + 8 * 3); /* rank 1's, across the border */
  S.work[border] = 50;
  S.work[next] = 40; /* (its block overlaps border's) */
  S.work[far] = 1;
  S.work[other] = 30;
  CU_ASSERT_EQUAL_FATAL(sched_pick_narrow(&S, 0, 8, t), 2);
  CU_ASSERT(t[0].cell == border && t[1].cell == far && !t[0].wide && !t[1].wide);
  CU_ASSERT(memcmp(before, S.holder, sizeof before) == 0);
  CU_ASSERT(S.lock[other] == 1 && S.lock[next] == 1 && S.inflight[0] == 2);
  CU_ASSERT_EQUAL(sched_pick_narrow(&S, 1, 8, t), 0); /* (other's block is locked) */
  sched_feedback(&S, 0, (sched_task_t[]){{border, false, 0}, {far, false, 0}}, 2, NULL, 0);
  S.work[border] = S.work[far] = 0;
  CU_ASSERT_EQUAL_FATAL(sched_pick_narrow(&S, 1, 8, t), 1);
  CU_ASSERT(t[0].cell == other);
  CU_ASSERT_EQUAL(sched_pick_narrow(&S, 0, 8, t), 0); /* (next's block meets other's) */
  CU_ASSERT(memcmp(before, S.holder, sizeof before) == 0);
  for (uint32_t c = 0; c < S.ncells; c++) CU_ASSERT(S.lock[c] <= 1);
  sched_free(&S);
}

static void test_best_rank_ties(void)
{
  const int32_t n[3] = {3, 3, 3};
  sched_t S;
  CU_ASSERT_FATAL(sched_init(&S, n, 4) == I2M_OK);
  for (uint32_t c = 0; c < 27; c++) S.holder[c] = (int32_t)(c % 2 ? 3 : 1); /* 13 cells to 3, 14 to 1 */
  CU_ASSERT_EQUAL(sched_best_rank(&S, (sched_task_t){13, false, 0}), 1);
  S.tets[1] = 5; /* rank 3 now holds 13 + 5 */
  CU_ASSERT_EQUAL(sched_best_rank(&S, (sched_task_t){13, false, 0}), 3);
  for (uint32_t c = 0; c < 27; c++) S.holder[c] = 2, S.tets[c] = 0;
  S.holder[0] = 0;
  S.holder[1] = 1;
  S.holder[2] = 3;
  CU_ASSERT_EQUAL(sched_best_rank(&S, (sched_task_t){0, false, 0}), 2); /* 5 of cell 0's 8 cells */
  for (uint32_t c = 0; c < 27; c++) S.holder[c] = (int32_t)(c % 4);
  S.tets[0] = 1; /* cell 0's block: cells 0,1,3,4,9,10,12,13: ranks 0,1,3,0,1,2,0,1 -> 0 has 3 + 1 */
  CU_ASSERT_EQUAL(sched_best_rank(&S, (sched_task_t){0, false, 0}), 0);
  S.tets[0] = 0; /* 0 and 1 hold three each: the lower */
  CU_ASSERT_EQUAL(sched_best_rank(&S, (sched_task_t){0, false, 0}), 0);
  S.tets[1] = 1;
  CU_ASSERT_EQUAL(sched_best_rank(&S, (sched_task_t){0, false, 0}), 1);
  sched_free(&S);
}

/* ---- sched_balance ---- */

static bool face_adjacent(const int32_t n[3], uint32_t a, uint32_t b)
{
  int32_t x[3], y[3];
  xyz(n, a, x);
  xyz(n, b, y);
  const int d = abs(x[0] - y[0]) + abs(x[1] - y[1]) + abs(x[2] - y[2]);
  return d == 1;
}

/* One plan, checked against the model: each move legal when made (the giver the most loaded
 * rank, the cell its own and next to the receiver's, the receiver below the giver after it),
 * each cell once, the loads and holders as the moves leave them, and at the end the bound met
 * or no legal move left.  Also: the same plan a second time. */
static bool check_balance(const int32_t n[3], int P, const int64_t *kept, const int32_t *holder0)
{
  const uint32_t nc = (uint32_t)(n[0] * n[1] * n[2]);
  int32_t *h = malloc(nc * sizeof *h), *h2 = malloc(nc * sizeof *h2), *model = malloc(nc * sizeof *model);
  sched_move_t *mv = malloc(nc * sizeof *mv), *mv2 = malloc(nc * sizeof *mv2);
  int64_t load[8], load2[8], ml[8] = {0};
  bool *moved = calloc(nc, sizeof *moved), ok = h && h2 && model && mv && mv2 && moved;
  if (ok) {
    memcpy(h, holder0, nc * sizeof *h);
    memcpy(h2, holder0, nc * sizeof *h2);
    memcpy(model, holder0, nc * sizeof *model);
  }
  const uint32_t nm = ok ? sched_balance(n, P, kept, h, mv, load) : 0;
  int64_t total = 0;
  for (uint32_t c = 0; ok && c < nc; c++) {
    ml[model[c]] += kept[c];
    total += kept[c];
  }
  const double bound = (double)total / P * (1.0 + SCHED_BALANCE_SLACK);
  for (uint32_t k = 0; ok && k < nm; k++) {
    const sched_move_t m = mv[k];
    int q = 0;
    for (int r = 1; r < P; r++) q = ml[r] > ml[q] ? r : q;
    bool next = false;
    for (uint32_t c = 0; c < nc; c++) next |= model[c] == m.to && face_adjacent(n, c, m.cell);
    ok = m.cell < nc && !moved[m.cell] && model[m.cell] == m.from && m.from == q && m.to != m.from && next &&
         ml[m.to] + kept[m.cell] < ml[m.from] && (double)ml[q] > bound;
    moved[m.cell] = true;
    model[m.cell] = m.to;
    ml[m.from] -= kept[m.cell];
    ml[m.to] += kept[m.cell];
  }
  for (uint32_t c = 0; ok && c < nc; c++) ok = h[c] == model[c];
  for (int r = 0; ok && r < P; r++) ok = load[r] == ml[r];
  int q = 0;
  for (int r = 1; ok && r < P; r++) q = ml[r] > ml[q] ? r : q;
  if (ok && (double)ml[q] > bound) /* then no legal move is left */
    for (uint32_t c = 0; c < nc; c++) {
      if (model[c] != q || moved[c] || kept[c] == 0) continue;
      for (uint32_t d = 0; d < nc; d++)
        if (model[d] != q && face_adjacent(n, c, d) && ml[model[d]] + kept[c] < ml[q]) ok = false;
    }
  const uint32_t nm2 = ok ? sched_balance(n, P, kept, h2, mv2, load2) : 0;
  ok = ok && nm2 == nm && memcmp(mv, mv2, nm * sizeof *mv) == 0;
  free(h);
  free(h2);
  free(model);
  free(mv);
  free(mv2);
  free(moved);
  return ok;
}

static void test_balance_by_hand(void)
{
  const int32_t n[3] = {4, 1, 1};
  const int64_t kept[4] = {10, 10, 10, 10};
  int32_t h[4] = {0, 0, 0, 1};
  sched_move_t mv[4];
  int64_t load[2];
  CU_ASSERT_EQUAL_FATAL(sched_balance(n, 2, kept, h, mv, load), 1);
  CU_ASSERT(mv[0].cell == 2 && mv[0].from == 0 && mv[0].to == 1); /* the one next to rank 1 */
  CU_ASSERT(load[0] == 20 && load[1] == 20 && h[2] == 1);
  const int64_t even[4] = {10, 10, 10, 10};
  int32_t h2[4] = {0, 0, 1, 1};
  CU_ASSERT_EQUAL(sched_balance(n, 2, even, h2, mv, load), 0); /* balanced already */
  const int64_t heavy[4] = {100, 1, 1, 1};
  int32_t h3[4] = {0, 1, 1, 1};
  CU_ASSERT_EQUAL(sched_balance(n, 2, heavy, h3, mv, load), 0); /* moving it would only swap the roles */
  int32_t h4[4] = {0, 0, 0, 0}; /* another rank holds nothing next to rank 0's cells: nothing moves */
  CU_ASSERT_EQUAL(sched_balance(n, 2, kept, h4, mv, load), 0);
  CU_ASSERT(load[0] == 40 && load[1] == 0);
  CU_ASSERT(check_balance(n, 2, kept, (const int32_t[4]){0, 0, 0, 1}));
}

static void test_balance_random(void)
{
  static const int32_t grids[][3] = {{8, 8, 8}, {6, 4, 5}, {3, 3, 3}, {2, 1, 7}};
  uint64_t seed = 42;
  for (size_t g = 0; g < sizeof grids / sizeof *grids; g++)
    for (int P = 2; P <= 5; P++)
      for (int trial = 0; trial < 20; trial++) {
        sched_t S;
        CU_ASSERT_FATAL(sched_init(&S, grids[g], P) == I2M_OK);
        for (uint32_t c = 0; c < S.ncells; c++) S.tets[c] = (int64_t)below(&seed, 1000) * (below(&seed, 5) != 0);
        sched_partition(&S);
        int64_t *kept = malloc(S.ncells * sizeof *kept);
        CU_ASSERT_FATAL(kept != NULL);
        for (uint32_t c = 0; c < S.ncells; c++) { /* drift: a run of cells along the grid goes to one rank */
          kept[c] = S.tets[c] * (int64_t)(1 + below(&seed, 3));
          S.holder[c] = S.home[c];
        }
        const uint32_t from = below(&seed, S.ncells), len = below(&seed, S.ncells / 2 + 1);
        const int32_t to = (int32_t)below(&seed, (uint32_t)P);
        for (uint32_t c = from; c < from + len && c < S.ncells; c++) S.holder[c] = to;
        const bool ok = check_balance(grids[g], P, kept, S.holder);
        CU_ASSERT(ok);
        if (!ok) fprintf(stderr, "grid %dx%dx%d, %d ranks, trial %d\n", grids[g][0], grids[g][1], grids[g][2], P, trial);
        free(kept);
        sched_free(&S);
      }
}

static const test_case_t tests[] = {
    {"sched_block: blocks clipped at faces, edges and corners", test_block_clipping},
    {"sched_partition: contiguous Morton shares, balanced tets", test_partition},
    {"sched_partition: every rank a share when cells >= ranks", test_partition_nonempty},
    {"asynchronous mode on 8x8x8, 1-5 ranks: no overlap, termination", test_async_cube},
    {"asynchronous mode on 6x4x5, 1-5 ranks: no overlap, termination", test_async_box},
    {"asynchronous mode on small grids", test_async_small},
    {"deterministic phases and the wide pass, 1-5 ranks", test_det_phases},
    {"sched_wide_list", test_wide_list},
    {"busy, wide tasks alone, blocks apart, by hand", test_busy_by_hand},
    {"fetching only for work worth the tets, or on a stall, by hand", test_move_worth},
    {"sched_pick_held: no fetch, even on a stall", test_pick_held},
    {"sched_pick_narrow: the cells a rank holds, nothing moves", test_pick_narrow},
    {"a task that skips sides fetches and takes only its fetch block, locks all", test_skip_sides},
    {"sched_best_rank and its ties", test_best_rank_ties},
    {"sched_balance by hand", test_balance_by_hand},
    {"sched_balance on random drifts, 2-5 ranks: legal moves, the bound or no move left", test_balance_random},
};
TEST_MAIN("the dist layer's task scheduler", tests)
