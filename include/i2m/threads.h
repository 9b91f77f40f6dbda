/* i2m threads layer (layer 5): shared-memory parallel refinement (ARCHITECTURE §5): OpenMP
 * worker threads on one triangulation, PODM-style speculative insertion and removal with
 * vertex locks and rollbacks, a priority contention manager, a begging list for load
 * balancing, pauses to grow capacity, a coarse phase, threads pinned to cores with hwloc. */
#ifndef I2M_THREADS_H
#define I2M_THREADS_H

#include "i2m/refine.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
  int threads;          /**< worker threads (0: the cores the process may use) */
  double coarse_factor; /**< the coarse phase uses size bounds x this factor (1: no coarse phase) */
  bool pin;             /**< bind thread k to the k-th core the process may use */
  bool deterministic;   /**< tiles instead of speculation: the same mesh on any number of threads */
  int depth;            /**< the octree's depth (the deterministic mode's fine tiles); 0: the default */
} i2m_threads_opts_t;

/** What one thread did. */
typedef struct {
  int64_t insertions, removals, rollbacks, waits, handoffs, given;
  double busy_seconds, idle_seconds, wait_seconds;
  int core; /**< the core it was bound to, -1 if not bound */
} i2m_thread_figures_t;

typedef struct {
  int threads;
  int pinned;                    /**< 1 if every thread was bound to its own core */
  char binding[160];             /**< how threads were placed */
  double coarse_seconds, fine_seconds;
  int64_t pauses;                /**< capacity growths with every thread paused */
  int deterministic;             /**< 1: the deterministic mode ran (tiles) */
  double tile_side;              /**< its tile side (mm) in the fine phase (the longest) */
  int depth;                     /**< the octree's depth in the fine phase (0: none) */
  int64_t phases, rounds;        /**< its parallel phases and rounds */
  int64_t sequential_ops;        /**< elements its sequential passes did */
  i2m_thread_figures_t *thread;  /**< owned: [threads]; free with i2m_threads_report_free */
} i2m_threads_report_t;

/** The cores the process may use (hwloc; 1 if unknown). */
int i2m_threads_available(void);

/** Threads when none are asked for: OMP_NUM_THREADS when it is set (its first entry), else
 *  the cores the process may use. */
int i2m_threads_default(void);

/** Caps every later OpenMP phase (distance transform, extraction, quality figures) at n
 *  (>= 1) threads, below the runtime's default (OMP_NUM_THREADS, else every hardware
 *  thread): a process asked for n threads uses at most n in any phase. */
void i2m_threads_limit(int n);

/** Sets the threads of every later OpenMP phase to n (>= 1), above the cap of
 *  i2m_threads_limit too, and returns the count it replaces (to restore it).  For a phase that
 *  one process runs while the others of its node wait asleep (i2m_par_node_threads). */
int i2m_threads_set(int n);

/** Refines to completion on o->threads threads (all rules, both phases).  Not collective. */
i2m_err_t i2m_threads_refine(i2m_refine_t *r, const i2m_threads_opts_t *o, i2m_threads_report_t *rep);
void i2m_threads_report_free(i2m_threads_report_t *rep);

/** The coarse phase alone (the dist layer's rank 0): refinement at coarse_factor x delta and
 *  the size bounds (speculative, or on the coarse tiles when deterministic), every tet of the
 *  block kept below the octree's background bound (its depth set before), then every tet
 *  classified again under the real bounds into the octree's tiles (left in place).  Not
 *  collective. */
i2m_err_t i2m_threads_coarse(i2m_refine_t *r, const i2m_threads_opts_t *o, i2m_threads_report_t *rep);

/** The sliver perturbation (i2m_refine_perturb_slivers) on the threads that refined (the
 *  tiles of one colour at a time): the same mesh whatever their number.  Not collective. */
i2m_err_t i2m_threads_perturb_slivers(i2m_refine_t *r, const i2m_threads_opts_t *o, double bound,
                                      i2m_sliver_stats_t *st);

/* ---- the worker pool of the dist layer (src/threads/pool.c) ---- */

/** What the pool's workers do. */
typedef enum {
  I2M_POOL_TILES,    /**< refine tiles (each by one worker, taken in turn) */
  I2M_POOL_WIDE,     /**< one tile's wide task (by the first worker) */
  I2M_POOL_CLASSIFY, /**< classify every tet again into the tiles (i2m_refine_tiling_classify) */
  I2M_POOL_SLIVERS   /**< the sliver perturbation of tiles (each by one worker) */
} i2m_pool_job_kind_t;

typedef struct {
  i2m_pool_job_kind_t kind;
  const uint32_t *tiles; /**< borrowed until the job ends */
  uint32_t ntiles;
  int64_t *created;      /**< borrowed, or NULL: [ntiles] the tets each tile's task made */
} i2m_pool_job_t;

typedef struct i2m_pool i2m_pool_t;

/** The nested master-worker model on one process: runs master(ctx, pool) on the calling
 *  thread (the one that initialised MPI: only it talks MPI) while o->threads worker threads
 *  run the jobs it starts; returns master's result.  Worker threads bound to cores from
 *  pin_offset (another process's workers may use the first ones).  Not collective. */
i2m_err_t i2m_threads_serve(i2m_refine_t *r, const i2m_threads_opts_t *o, int pin_offset,
                            i2m_err_t (*master)(void *ctx, i2m_pool_t *pool), void *ctx, i2m_threads_report_t *rep);
/** Master: starts a job (none running); returns at once. */
void i2m_pool_start(i2m_pool_t *p, const i2m_pool_job_t *job);
/** Master: has the job ended?  Then *err is its result (the message set). */
bool i2m_pool_finished(i2m_pool_t *p, i2m_err_t *err);
/** Master: a job to its end. */
i2m_err_t i2m_pool_run(i2m_pool_t *p, const i2m_pool_job_t *job);
int i2m_pool_threads(const i2m_pool_t *p);

#ifdef __cplusplus
}
#endif
#endif
