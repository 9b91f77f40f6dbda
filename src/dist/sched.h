/* Dist layer internals: the task scheduler of rank 0 (hybrid paper, §3.2 and Fig. 2), pure
 * bookkeeping without MPI, so that its invariants are unit-tested on their own.
 *
 * The octree's 8^d cells are the subregions.  A task is a cell: it refines the cell's bad
 * elements inside a zone that reaches half a cell into its neighbours, reading and changing
 * only the tets of its block (the cell and its 26 neighbours: the first buffer zone); a wide
 * task reads a block of 5^3 cells.  The scheduler never runs two tasks whose blocks overlap
 * (centres at least 3 cells apart: the second buffer zone), so tasks in flight never
 * synchronise.  It knows, from the feedback after each task, the bad elements of every cell
 * (normal and wide) and the tets it holds, and where every cell's submesh lives (the Location
 * array): a task goes to the rank that asks, the one whose blocks' submeshes it already holds
 * first; its block's cells then belong to that rank.  A task whose few elements all lie away
 * from some sides of its cell (its feedback says which: skip) needs only the part of its block
 * on the other sides (its fetch block): it still locks the whole block, but fetches, takes and
 * is priced by that part only.  Ranks that ask while nothing can be given wait in a list; the
 * run ends exactly when no cell has work and no task is in flight. */
#ifndef I2M_DIST_SCHED_H
#define I2M_DIST_SCHED_H

#include <stdbool.h>
#include <stdint.h>

#include "i2m/base.h"

/** A rank that fetches submeshes for a task may come to hold at most this many times its
 *  share (1 / ranks) of the tets (then it takes only tasks whose data it holds). */
#define SCHED_HOLD_SHARE 1.3

/** A rank fetches data for a task only when the task's bad elements times this reach the tets
 *  it fetches (unless the run would stall otherwise).  A bad element costs about 4 insertions
 *  (the knee: 1.73 M insertions from 456 k bad elements at the start), each ~14 us, and a tet
 *  moved ~0.9 us of packing, sending, joining and dropping: break-even near 60.  On the knee
 *  at 2 ranks, 58% of the tets fetched went to tasks that fetched over 1000 per bad element
 *  (about 9 bad elements, 100 k tets); 30 left one rank idle for a third of the run. */
#define SCHED_MOVE_WORTH 60.0

/** A task: a cell (wide: its wide task, a block of 5^3 cells).  A normal task whose elements
 *  all lie away from some sides of its cell (skip) runs on the part of its block on the
 *  others (its fetch block): it locks the whole block, but the cells beyond the skipped sides
 *  are neither fetched nor taken, and its zone stops short of them (i2m_refine_tile_skip). */
typedef struct {
  uint32_t cell;
  bool wide;
  uint8_t skip; /* sides skipped (bit 2a: the lower face along axis a, 2a + 1: the upper; 0: the whole block) */
} sched_task_t;

/** What a rank tells the scheduler about one cell after a task. */
typedef struct {
  uint32_t cell;
  int64_t work, wide, tets; /* bad elements, of them for the wide task, tets held */
  int64_t points;           /* bridge points its task inserts first (counted in work) */
  int64_t wpoints;          /* bridge points its wide task inserts first (counted in wide) */
  int64_t skip;             /* sides its task may skip (i2m_refine_tile_figures) */
} sched_cell_t;

typedef struct {
  int32_t n[3];      /* cells along each axis */
  uint32_t ncells;
  int nranks;
  int64_t *work;     /* [ncells] bad elements for the cell's task */
  int64_t *wide;     /* [ncells] bad elements for its wide task */
  int64_t *tets;     /* [ncells] tets of its submesh */
  int64_t *points;   /* [ncells] bridge points for its task (the deterministic mode's first stage) */
  int64_t *wpoints;  /* [ncells] bridge points for its wide task (the same stage's end) */
  uint8_t *skip;     /* [ncells] sides its task may skip (asynchronous mode; 0: none) */
  int32_t *holder;   /* [ncells] the rank that holds its submesh (Location) */
  int32_t *home;     /* [ncells] the rank whose share of the block the cell is in (sched_partition) */
  uint32_t *lock;    /* [ncells] tasks in flight whose block holds it */
  int32_t *inflight; /* [nranks] tasks each rank is running */
  bool *waiting;     /* [nranks] ranks on the waiting list */
  bool *done;        /* [nranks] ranks told to stop */
  int64_t *held;     /* [nranks] scratch of sched_pick: the tets each rank holds (+1 a cell) */
  int64_t tasks_given, wide_given;
} sched_t;

i2m_err_t sched_init(sched_t *S, const int32_t n[3], int nranks);

/** Cuts the cells into one share per rank (home), contiguous along a Morton curve, each with
 *  about the same number of tets (the coarse mesh's: where the fine mesh will be dense too). */
void sched_partition(sched_t *S);
void sched_free(sched_t *S);

/** The cells of a task's block (radius 1, or 2 for a wide task), clipped to the grid:
 *  cells[] gets them (room for 125), returns their number. */
uint32_t sched_block(const sched_t *S, sched_task_t t, uint32_t *cells);

/** The cells of task t's block that it needs present (its fetch block: the block without the
 *  layers beyond the sides it skips), as sched_block. */
uint32_t sched_fetch_block(const sched_t *S, sched_task_t t, uint32_t *cells);

/** Can task t run now (it has work, and no cell of its block is locked)? */
bool sched_runnable(const sched_t *S, sched_task_t t);

/** Up to max tasks for `rank` (asynchronous mode): cells with work whose blocks are free and
 *  do not overlap each other: cells of its share first, those whose block it holds most of
 *  first (then the busiest); then others' (the data follows the work, while the rank holds
 *  less than SCHED_HOLD_SHARE times its share of the tets, when the work is worth the tets
 *  fetched (SCHED_MOVE_WORTH), and only when no busy rank holds more of the block, unless
 *  that one holds more than SCHED_HOLD_SHARE times its share: it will ask again; when every
 *  other rank waits with nothing in flight, only the first bound holds, and only while
 *  sched_other_could_run: then this rank gets nothing and the waiting ones are served).
 *  Their blocks are
 *  locked and now belong to the rank.  Returns their number (0: nothing can run now).  A wide
 *  task comes alone. */
uint32_t sched_pick(sched_t *S, int rank, uint32_t max, sched_task_t *out);

/** As sched_pick, but only tasks whose whole block `rank` holds (nothing fetched). */
uint32_t sched_pick_held(sched_t *S, int rank, uint32_t max, sched_task_t *out);

/** As sched_pick_held, but tasks of the cells `rank` holds, whatever it holds of their
 *  blocks: their blocks are locked and nothing moves (the holders stay as they are).  The
 *  task works on the tets its rank holds; a change that would reach another rank's stops there
 *  (the kernel's frozen faces) and waits for a task that fetches.  The most work first. */
uint32_t sched_pick_narrow(sched_t *S, int rank, uint32_t max, sched_task_t *out);

/** Does any rank run tasks? */
bool sched_in_flight(const sched_t *S);

/** Could a waiting rank other than `rank` run a task now, fetching no more than
 *  SCHED_HOLD_SHARE times its share of the tets? */
bool sched_other_could_run(sched_t *S, int rank);

/** The feedback of a rank's tasks: their blocks unlocked, the cells' figures updated. */
void sched_feedback(sched_t *S, int rank, const sched_task_t *tasks, uint32_t ntasks, const sched_cell_t *cells,
                    uint32_t ncells);

/** Is there work left anywhere, or a task in flight? */
bool sched_busy(const sched_t *S);

/** The deterministic mode's phase: the tasks of one colour (the cells whose coordinates
 *  modulo 3 make it) that have work (points_only: bridge points), most work first, each
 *  assigned (owner[k]) to the rank that holds most of its block (the data stays put), unless
 *  that rank would fetch data and come to hold more than SCHED_HOLD_SHARE times its share of
 *  the tets: then to the rank that would hold least after it; their blocks locked and given
 *  to their ranks.  Returns their number. */
uint32_t sched_phase(sched_t *S, int color, bool points_only, sched_task_t *out, int *owner);

/** Has some cell bridge points still to insert? */
bool sched_has_points(const sched_t *S);

/** The deterministic mode's wide pass: the cells with wide work, in order (points: only those
 *  whose wide task has bridge points, right after the stage of the points). */
uint32_t sched_wide_list(const sched_t *S, bool points, uint32_t *out);

/** A task given to a rank (its block locked and now the rank's). */
void sched_give(sched_t *S, int rank, sched_task_t t);

/** The rank that holds the most tets of task t's fetch block. */
int sched_best_rank(const sched_t *S, sched_task_t t);

/** A rank that holds more than this above the mean of the output tets gives cells away
 *  (sched_balance). */
#define SCHED_BALANCE_SLACK 0.05

/** A cell that moves from one rank to another (sched_balance). */
typedef struct {
  uint32_t cell;
  int from, to;
} sched_move_t;

/** The moves that spread kept[] (each cell's output tets) over P ranks, on a grid of n cells,
 *  greedily: the most loaded rank gives the rank with the least load among those across a
 *  face of its cells the cell next to it whose tets come closest to what both need to reach
 *  the mean, as long as the receiver stays below the giver; each cell moves once at most;
 *  until no rank holds more than SCHED_BALANCE_SLACK above the mean, or no such move is left.
 *  holder[] is updated, load[] ([P]) gets each rank's tets after; moves[] (room for every
 *  cell) gets the moves in order.  Returns their number.  The same on every rank given the
 *  same counts. */
/** The rank with the most of load[0..P) (the lowest on ties). */
int sched_most_loaded(const int64_t *load, int P);

uint32_t sched_balance(const int32_t n[3], int P, const int64_t *kept, int32_t *holder, sched_move_t *moves,
                       int64_t *load);

#endif
