/* Dist layer: the task scheduler of rank 0 (see sched.h).  No MPI here. */
#include "sched.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

i2m_err_t sched_init(sched_t *S, const int32_t n[3], int nranks)
{
  memset(S, 0, sizeof *S);
  for (int a = 0; a < 3; a++) S->n[a] = n[a];
  S->ncells = (uint32_t)n[0] * (uint32_t)n[1] * (uint32_t)n[2];
  S->nranks = nranks;
  const size_t c = S->ncells;
  i2m_err_t err = I2M_OK;
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->work, &S->work);
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->wide, &S->wide);
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->tets, &S->tets);
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->points, &S->points);
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->wpoints, &S->wpoints);
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->skip, &S->skip);
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->holder, &S->holder); /* rank 0 holds the coarse mesh */
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->home, &S->home);
  if (err == I2M_OK) err = i2m_calloc(c, sizeof *S->lock, &S->lock);
  if (err == I2M_OK) err = i2m_calloc((size_t)nranks, sizeof *S->inflight, &S->inflight);
  if (err == I2M_OK) err = i2m_calloc((size_t)nranks, sizeof *S->waiting, &S->waiting);
  if (err == I2M_OK) err = i2m_calloc((size_t)nranks, sizeof *S->done, &S->done);
  if (err == I2M_OK) err = i2m_calloc((size_t)nranks, sizeof *S->held, &S->held);
  if (err != I2M_OK) sched_free(S);
  return err;
}

void sched_free(sched_t *S)
{
  i2m_free(&S->work);
  i2m_free(&S->wide);
  i2m_free(&S->tets);
  i2m_free(&S->points);
  i2m_free(&S->wpoints);
  i2m_free(&S->skip);
  i2m_free(&S->holder);
  i2m_free(&S->home);
  i2m_free(&S->lock);
  i2m_free(&S->inflight);
  i2m_free(&S->waiting);
  i2m_free(&S->done);
  i2m_free(&S->held);
}

/* Cell c's coordinates on a grid of n cells. */
static void grid_coords(const int32_t n[3], uint32_t c, int32_t x[3])
{
  x[0] = (int32_t)(c % (uint32_t)n[0]);
  x[1] = (int32_t)(c / (uint32_t)n[0] % (uint32_t)n[1]);
  x[2] = (int32_t)(c / (uint32_t)n[0] / (uint32_t)n[1]);
}

static void coords(const sched_t *S, uint32_t c, int32_t x[3]) { grid_coords(S->n, c, x); }

/* The position of cell c on a Morton (Z-order) curve: its coordinates' bits interleaved. */
static uint64_t morton(const sched_t *S, uint32_t c)
{
  int32_t x[3];
  coords(S, c, x);
  uint64_t key = 0;
  for (int b = 0; b < 21; b++)
    for (int a = 0; a < 3; a++) key |= (uint64_t)((x[a] >> b) & 1) << (3 * b + a);
  return key;
}

static int cmp_u64(const void *a, const void *b)
{
  const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return (x > y) - (x < y);
}

void sched_partition(sched_t *S)
{
  uint64_t *order = NULL;
  if (i2m_malloc(S->ncells, sizeof *order, &order) != I2M_OK) return; /* (homes stay rank 0's) */
  int64_t total = 0;
  for (uint32_t c = 0; c < S->ncells; c++) {
    order[c] = morton(S, c) << 32 | c; /* (morton < 2^30 for the depths allowed) */
    total += S->tets[c] + 1;
  }
  qsort(order, S->ncells, sizeof *order, cmp_u64);
  /* share q begins where the tets before reach q/P of the whole (a cell goes to the share its
   * middle falls in), but every share gets one cell at least when there are enough */
  int64_t acc = 0;
  uint32_t begin = 0; /* the first cell of the current share */
  int q = 0;
  for (uint32_t i = 0; i < S->ncells; i++) {
    const uint32_t c = (uint32_t)order[i];
    const int64_t w = S->tets[c] + 1;
    int want = (int)((acc + w / 2) * S->nranks / total);
    const uint32_t left = S->ncells - i; /* cells from this one on */
    /* the next share begins here if the tets say so, or if no more cells than empty shares are
     * left; never skipping one, never before the current one has a cell */
    if (i > begin && q < S->nranks - 1 && (want > q || (int)left <= S->nranks - 1 - q)) {
      q++;
      begin = i;
    }
    S->home[c] = q;
    acc += w;
  }
  i2m_free(&order);
}

/* The cells of task t's block, without the layers beyond the sides in skip. */
static uint32_t block_cells(const sched_t *S, sched_task_t t, unsigned skip, uint32_t *cells)
{
  const int rad = t.wide ? 2 : 1;
  int32_t c[3], lo[3], hi[3];
  coords(S, t.cell, c);
  for (int a = 0; a < 3; a++) {
    const int rlo = skip >> (2 * a) & 1 ? 0 : rad, rhi = skip >> (2 * a + 1) & 1 ? 0 : rad;
    lo[a] = c[a] - rlo < 0 ? 0 : c[a] - rlo;
    hi[a] = c[a] + rhi >= S->n[a] ? S->n[a] - 1 : c[a] + rhi;
  }
  uint32_t n = 0;
  for (int32_t k = lo[2]; k <= hi[2]; k++)
    for (int32_t j = lo[1]; j <= hi[1]; j++)
      for (int32_t i = lo[0]; i <= hi[0]; i++)
        cells[n++] = ((uint32_t)k * (uint32_t)S->n[1] + (uint32_t)j) * (uint32_t)S->n[0] + (uint32_t)i;
  return n;
}

uint32_t sched_block(const sched_t *S, sched_task_t t, uint32_t *cells) { return block_cells(S, t, 0, cells); }

uint32_t sched_fetch_block(const sched_t *S, sched_task_t t, uint32_t *cells)
{
  return block_cells(S, t, t.wide ? 0 : t.skip, cells);
}

static bool has_work(const sched_t *S, sched_task_t t) { return (t.wide ? S->wide[t.cell] : S->work[t.cell]) > 0; }

bool sched_runnable(const sched_t *S, sched_task_t t)
{
  if (!has_work(S, t)) return false;
  uint32_t cells[125];
  const uint32_t n = sched_block(S, t, cells);
  for (uint32_t i = 0; i < n; i++)
    if (S->lock[cells[i]]) return false;
  return true;
}

/* Task t given to `rank`: its block locked, and (take) its fetch block's cells now the rank's. */
static void lock_task(sched_t *S, int rank, sched_task_t t, bool take)
{
  uint32_t cells[125];
  uint32_t n = sched_block(S, t, cells);
  for (uint32_t i = 0; i < n; i++) S->lock[cells[i]]++;
  n = take ? sched_fetch_block(S, t, cells) : 0;
  for (uint32_t i = 0; i < n; i++) S->holder[cells[i]] = rank;
  S->inflight[rank]++;
  S->tasks_given++;
  S->wide_given += t.wide;
}

void sched_give(sched_t *S, int rank, sched_task_t t) { lock_task(S, rank, t, true); }

/* Tets of task t's fetch block that `rank` would have to fetch. */
static int64_t to_move(const sched_t *S, int rank, sched_task_t t)
{
  uint32_t cells[125];
  const uint32_t n = sched_fetch_block(S, t, cells);
  int64_t m = 0;
  for (uint32_t i = 0; i < n; i++)
    if (S->holder[cells[i]] != rank) m += S->tets[cells[i]] + 1;
  return m;
}

/* The tets each rank holds into S->held, and in all (the last figures fed back; a cell weighs
 * one more, as in to_move). */
static int64_t held_tets(sched_t *S)
{
  int64_t total = 0;
  for (int q = 0; q < S->nranks; q++) S->held[q] = 0;
  for (uint32_t c = 0; c < S->ncells; c++) {
    total += S->tets[c] + 1;
    S->held[S->holder[c]] += S->tets[c] + 1;
  }
  return total;
}

/* May `rank` fetch data for task t?  Not when another rank holds more of its block, will ask
 * again (it is busy) and holds no more than SCHED_HOLD_SHARE times its share of the tets
 * (held[], before the pick: a rank that holds that much may be relieved of some):
 * the task waits for it, instead of the block's data moving back and forth between the ranks
 * at the borders of their shares. */
static bool best_place(const sched_t *S, int rank, sched_task_t t, const int64_t *held, int64_t total)
{
  const int b = sched_best_rank(S, t);
  return b == rank || S->waiting[b] || S->done[b] || (double)held[b] * S->nranks > (double)total * SCHED_HOLD_SHARE;
}

/* What a rank that fetches data may come to hold: not much more than its share, so that memory
 * stays spread (the data follows the work, but not all of it to the fastest rank). */
static int64_t hold_cap(const sched_t *S, int64_t total)
{
  return S->nranks > 1 ? (int64_t)((double)total * SCHED_HOLD_SHARE / S->nranks) : INT64_MAX;
}

/* Would `rank` hold at most cap tets after fetching m for a task (a task that fetches nothing
 * always may)? */
static bool within_cap(const sched_t *S, int rank, int64_t m, int64_t cap)
{
  return m == 0 || S->held[rank] + m <= cap;
}

/* Is task t's work worth fetching m tets for?  Not when SCHED_MOVE_WORTH times its bad
 * elements are fewer: the task waits for a rank that holds more of its block, or for a stall. */
static bool worth_moving(const sched_t *S, sched_task_t t, int64_t m)
{
  const int64_t work = t.wide ? S->wide[t.cell] : S->work[t.cell];
  return (double)work * SCHED_MOVE_WORTH >= (double)m;
}

/* May `rank` fetch m tets for task t, besides the memory cap (see sched_pick)? */
static bool may_fetch(const sched_t *S, int rank, sched_task_t t, int64_t m, int64_t total)
{
  return best_place(S, rank, t, S->held, total) && worth_moving(S, t, m);
}

/* The tasks for `rank` (see sched_pick) when it may hold at most cap tets after a fetch, and,
 * when stalled, may fetch for any task. */
static uint32_t pick_tasks(sched_t *S, int rank, uint32_t max, sched_task_t *out, int64_t total, int64_t cap, bool stalled)
{
  uint32_t k = 0;
  while (k < max) {
    sched_task_t best = {0, false, 0};
    int best_home = 0;
    int64_t best_move = INT64_MAX, best_work = -1;
    for (uint32_t c = 0; c < S->ncells; c++) { /* the cheapest to fetch, its share first, the busiest */
      const sched_task_t t = {c, false, S->skip[c]};
      if (!sched_runnable(S, t)) continue;
      const int h = S->home[c] == rank;
      const int64_t m = to_move(S, rank, t);
      if (!within_cap(S, rank, m, cap)) continue;
      if (m > 0 && !stalled && !may_fetch(S, rank, t, m, total)) continue;
      if (m < best_move || (m == best_move && (h > best_home || (h == best_home && S->work[c] > best_work)))) {
        best = t;
        best_home = h;
        best_move = m;
        best_work = S->work[c];
      }
    }
    if (best_work < 0 && k == 0) /* no normal task: a wide one, alone */
      for (uint32_t c = 0; c < S->ncells; c++) {
        const sched_task_t t = {c, true, 0};
        if (!sched_runnable(S, t)) continue;
        const int64_t m = to_move(S, rank, t);
        if (!within_cap(S, rank, m, cap) || (m > 0 && !stalled && !may_fetch(S, rank, t, m, total))) continue;
        sched_give(S, rank, t);
        out[0] = t;
        return 1;
      }
    if (best_work < 0 || (k > 0 && best_move > 0)) break; /* (one task that fetches data per batch, first) */
    sched_give(S, rank, best);
    out[k++] = best;
  }
  return k;
}

bool sched_other_could_run(sched_t *S, int rank)
{
  const int64_t total = held_tets(S), cap = hold_cap(S, total);
  for (int q = 0; q < S->nranks; q++) {
    if (q == rank || !S->waiting[q]) continue;
    for (uint32_t c = 0; c < S->ncells; c++)
      for (int w = 0; w < 2; w++) {
        const sched_task_t t = {c, w != 0, w ? 0 : S->skip[c]};
        if (!sched_runnable(S, t)) continue;
        if (within_cap(S, q, to_move(S, q, t), cap)) return true;
      }
  }
  return false;
}

uint32_t sched_pick(sched_t *S, int rank, uint32_t max, sched_task_t *out)
{
  const int64_t total = held_tets(S);
  const int64_t cap = hold_cap(S, total);
  bool stalled = true; /* (nothing in flight, every other rank waiting: none would ever be served) */
  for (int q = 0; q < S->nranks; q++) stalled &= S->inflight[q] == 0 && (q == rank || S->waiting[q] || S->done[q]);
  if (!stalled) return pick_tasks(S, rank, max, out, total, cap, false);
  /* a stall: any task may fetch, within the cap while a waiting rank could run one within
   * its own (it is served next: the run stays spread over the ranks), else beyond */
  const uint32_t n = pick_tasks(S, rank, max, out, total, cap, true);
  if (n || sched_other_could_run(S, rank)) return n;
  return pick_tasks(S, rank, max, out, total, INT64_MAX, true);
}

uint32_t sched_pick_held(sched_t *S, int rank, uint32_t max, sched_task_t *out)
{
  const int64_t total = held_tets(S);
  return pick_tasks(S, rank, max, out, total, -1, false); /* (a cap below 0: no fetch is within it) */
}

uint32_t sched_pick_narrow(sched_t *S, int rank, uint32_t max, sched_task_t *out)
{
  uint32_t k = 0;
  while (k < max) {
    int64_t best_work = 0;
    uint32_t best = 0;
    for (uint32_t c = 0; c < S->ncells; c++) {
      const sched_task_t t = {c, false, 0};
      if (S->holder[c] == rank && S->work[c] > best_work && sched_runnable(S, t)) {
        best = c;
        best_work = S->work[c];
      }
    }
    if (best_work == 0) break;
    out[k] = (sched_task_t){best, false, 0};
    lock_task(S, rank, out[k++], false);
  }
  return k;
}

bool sched_in_flight(const sched_t *S)
{
  for (int r = 0; r < S->nranks; r++)
    if (S->inflight[r]) return true;
  return false;
}

void sched_feedback(sched_t *S, int rank, const sched_task_t *tasks, uint32_t ntasks, const sched_cell_t *cells,
                    uint32_t ncells)
{
  for (uint32_t i = 0; i < ntasks; i++) {
    uint32_t b[125];
    const uint32_t n = sched_block(S, tasks[i], b);
    for (uint32_t j = 0; j < n; j++) S->lock[b[j]]--;
    S->inflight[rank]--;
  }
  for (uint32_t i = 0; i < ncells; i++) {
    const sched_cell_t *c = &cells[i];
    S->work[c->cell] = c->work;
    S->wide[c->cell] = c->wide;
    S->tets[c->cell] = c->tets;
    S->points[c->cell] = c->points;
    S->wpoints[c->cell] = c->wpoints;
    S->skip[c->cell] = (uint8_t)c->skip;
  }
}

bool sched_has_points(const sched_t *S)
{
  for (uint32_t c = 0; c < S->ncells; c++)
    if (S->points[c]) return true;
  return false;
}

bool sched_busy(const sched_t *S)
{
  if (sched_in_flight(S)) return true;
  for (uint32_t c = 0; c < S->ncells; c++)
    if (S->work[c] || S->wide[c]) return true;
  return false;
}

int sched_best_rank(const sched_t *S, sched_task_t t)
{
  uint32_t cells[125];
  const uint32_t n = sched_fetch_block(S, t, cells);
  int best = 0;
  int64_t most = -1;
  for (int r = 0; r < S->nranks; r++) {
    int64_t held = 0;
    for (uint32_t i = 0; i < n; i++)
      if (S->holder[cells[i]] == r) held += S->tets[cells[i]] + 1;
    if (held > most) {
      most = held;
      best = r;
    }
  }
  return best;
}

typedef struct {
  int64_t work;
  uint32_t cell;
} by_work_t;

static int cmp_by_work(const void *a, const void *b)
{
  const by_work_t *x = a, *y = b;
  if (x->work != y->work) return x->work > y->work ? -1 : 1;
  return (x->cell > y->cell) - (x->cell < y->cell);
}

/* The rank for task t in a deterministic phase: the one that holds most of its block (the data
 * stays put), unless it would fetch some and come to hold more than SCHED_HOLD_SHARE times its
 * share of the tets; then the one that would hold least after the task (the least to fetch on
 * a tie, then the lowest).  Without the bound one rank took nearly every task of the knee at 2
 * ranks: the cells it refined weigh most in their neighbours' blocks, so their tasks went to
 * it, and their neighbours' after them. */
static int phase_rank(const sched_t *S, sched_task_t t, const int64_t *held, int64_t total)
{
  const int best = sched_best_rank(S, t);
  const int64_t m = to_move(S, best, t);
  if (m == 0 || (double)(held[best] + m) * S->nranks <= (double)total * SCHED_HOLD_SHARE) return best;
  int pick = best;
  int64_t least = held[best] + m, least_move = m;
  for (int r = 0; r < S->nranks; r++) {
    const int64_t mr = to_move(S, r, t);
    if (held[r] + mr < least || (held[r] + mr == least && mr < least_move)) {
      least = held[r] + mr;
      least_move = mr;
      pick = r;
    }
  }
  return pick;
}

uint32_t sched_phase(sched_t *S, int color, bool points_only, sched_task_t *out, int *owner)
{
  by_work_t *list = NULL;
  if (i2m_malloc(S->ncells, sizeof *list, &list) != I2M_OK) return UINT32_MAX;
  uint32_t n = 0;
  for (uint32_t c = 0; c < S->ncells; c++) {
    int32_t x[3];
    coords(S, c, x);
    const int64_t w = points_only ? S->points[c] : S->work[c];
    if (x[0] % 3 + 3 * (x[1] % 3) + 9 * (x[2] % 3) == color && w > 0) list[n++] = (by_work_t){w, c};
  }
  qsort(list, n, sizeof *list, cmp_by_work);
  int64_t total = held_tets(S);
  for (uint32_t k = 0; k < n; k++) {
    const sched_task_t t = {list[k].cell, false, 0};
    const int r = phase_rank(S, t, S->held, total);
    out[k] = t;
    owner[k] = r;
    sched_give(S, r, t);
    total = held_tets(S);
  }
  i2m_free(&list);
  return n;
}

uint32_t sched_wide_list(const sched_t *S, bool points, uint32_t *out)
{
  uint32_t n = 0;
  for (uint32_t c = 0; c < S->ncells; c++)
    if ((points ? S->wpoints[c] : S->wide[c]) > 0) out[n++] = c;
  return n;
}

int sched_most_loaded(const int64_t *load, int P)
{
  int q = 0;
  for (int k = 1; k < P; k++)
    if (load[k] > load[q]) q = k;
  return q;
}

/* The face neighbours of cell c (clipped to the grid): out[] gets them, returns how many. */
static int face_neighbours(const int32_t n[3], uint32_t c, uint32_t out[6])
{
  int32_t x[3];
  grid_coords(n, c, x);
  int k = 0;
  for (int a = 0; a < 3; a++)
    for (int d = -1; d <= 1; d += 2) {
      int32_t y[3] = {x[0], x[1], x[2]};
      y[a] += d;
      if (y[a] < 0 || y[a] >= n[a]) continue;
      out[k++] = ((uint32_t)y[2] * (uint32_t)n[1] + (uint32_t)y[1]) * (uint32_t)n[0] + (uint32_t)y[0];
    }
  return k;
}

/* ---- the output tets spread over the ranks (i2m_dist_balance) ---- */

uint32_t sched_balance(const int32_t n[3], int P, const int64_t *kept, int32_t *holder, sched_move_t *moves, int64_t *load)
{
  const uint32_t nc = (uint32_t)n[0] * (uint32_t)n[1] * (uint32_t)n[2];
  int64_t total = 0;
  for (int q = 0; q < P; q++) load[q] = 0;
  for (uint32_t c = 0; c < nc; c++) {
    load[holder[c]] += kept[c];
    total += kept[c];
  }
  const double mean = (double)total / P, bound = mean * (1.0 + SCHED_BALANCE_SLACK);
  uint32_t nm = 0;
  bool *moved = NULL;
  if (i2m_calloc(nc, sizeof *moved, &moved) != I2M_OK) return 0; /* (no plan: the ranks keep what they hold) */
  while (nm < nc) {
    const int q = sched_most_loaded(load, P);
    if ((double)load[q] <= bound) break;
    int64_t best_load = INT64_MAX;
    double best_gap = INFINITY;
    uint32_t best_c = 0;
    int best_r = -1;
    for (uint32_t c = 0; c < nc; c++) {
      if (holder[c] != q || moved[c] || kept[c] == 0) continue;
      uint32_t nb[6];
      const int k = face_neighbours(n, c, nb);
      for (int i = 0; i < k; i++) {
        const int r = holder[nb[i]];
        if (r == q || load[r] + kept[c] >= load[q]) continue;
        const double want = fmin((double)load[q] - mean, mean - (double)load[r]);
        const double gap = fabs((double)kept[c] - want);
        if (load[r] < best_load || (load[r] == best_load && gap < best_gap)) {
          best_load = load[r];
          best_gap = gap;
          best_c = c;
          best_r = r;
        }
      }
    }
    if (best_r < 0) break; /* (no cell of q touches a rank it could give to) */
    moves[nm++] = (sched_move_t){best_c, q, best_r};
    moved[best_c] = true;
    holder[best_c] = best_r;
    load[q] -= kept[best_c];
    load[best_r] += kept[best_c];
  }
  i2m_free(&moved);
  return nm;
}
