/* i2m dist layer (layer 6): the distributed-memory level (hybrid paper §3; ARCHITECTURE §6).
 *
 * A parallel context (communicator, rank, size, threads, log prefix) is what every collective
 * call takes, after p4est and PETSc; without MPI (or without a launcher) it holds a stand-in
 * communicator of one process.  i2m_dist_refine runs the nested master-worker model: rank 0's
 * threads build the coarse mesh, the octree's cells are the tasks, rank 0's master thread
 * schedules them (two-level buffer zones, a waiting list, termination when no cell has work and
 * no task is in flight), and on every rank the thread that initialised MPI is the only one to
 * call MPI (MPI_THREAD_FUNNELED): it asks for tasks, fetches the submeshes of their blocks from
 * the ranks that hold them, answers such requests at any time (also while its worker threads
 * refine), and reports the bad elements left per cell.  Submeshes stay where they were
 * refined until another task needs them. */
#ifndef I2M_DIST_H
#define I2M_DIST_H

#include <stdbool.h>
#include <stdint.h>

#if I2M_HAVE_MPI
#include <mpi.h>
#endif

#include "i2m/quality.h"
#include "i2m/refine.h"
#include "i2m/tetmesh.h"
#include "i2m/threads.h"

#ifdef __cplusplus
extern "C" {
#endif

/** The parallel context. */
typedef struct {
#if I2M_HAVE_MPI
  MPI_Comm comm;          /**< owned: a duplicate of MPI_COMM_WORLD (MPI_COMM_NULL without MPI) */
#else
  int comm;               /**< stand-in */
#endif
  int rank, size;
  int local_rank, local_size; /**< among the processes of this node */
  int threads;            /**< worker threads per process (0: not chosen yet) */
  bool mpi;               /**< MPI was initialised by i2m_par_init (and is finalised by i2m_par_finalize) */
  char prefix[32];        /**< "[rank 3] " when size > 1, else "" */
} i2m_par_t;

/** Starts MPI (MPI_Init_thread asking for MPI_THREAD_FUNNELED) when a launcher (mpirun,
 *  mpiexec, srun) started the process, else makes a context of one process (I2M_MPI=1 or 0 in
 *  the environment forces either).  Fails with a clear message when the MPI library gives
 *  less than MPI_THREAD_FUNNELED.  Collective on MPI_COMM_WORLD. */
i2m_err_t i2m_par_init(int *argc, char ***argv, i2m_par_t *par);
/** A context of one process that never calls MPI (the library call's; also in MPI builds). */
void i2m_par_self(i2m_par_t *par);
/** Frees the communicator and finalises MPI if i2m_par_init started it. */
void i2m_par_finalize(i2m_par_t *par);
/** Agrees on an error (collective): every rank returns the error of the lowest rank that
 *  failed, with its message (prefixed with that rank when there are several), or I2M_OK. */
i2m_err_t i2m_par_agree(const i2m_par_t *par, i2m_err_t err);
/** Ends every process of the run at once (MPI_Abort), with exit code `code`. */
void i2m_par_abort(const i2m_par_t *par, int code);
/** Largest / smallest / sum of a double over the ranks (collective). */
double i2m_par_max(const i2m_par_t *par, double x);
double i2m_par_sum(const i2m_par_t *par, double x);
/** Sum of 64-bit counters over the ranks, in place (collective). */
void i2m_par_sum_i64(const i2m_par_t *par, int64_t *x, int n);
/** The same int from rank 0 on every rank (collective). */
int i2m_par_bcast_int(const i2m_par_t *par, int x);
/** Waits for every rank (collective). */
void i2m_par_barrier(const i2m_par_t *par);
/** Threads for a phase this process runs alone while the other processes of its node wait
 *  asleep (i2m_par_agree): T for each process of the node, within the cores this process
 *  may use (no more than T when the launcher binds it to its own), never fewer than T. */
int i2m_par_node_threads(const i2m_par_t *par, int T);

/** Reads the image on rank 0 (i2m_image_read_with) and broadcasts it: every rank gets the
 *  same image, the file is read and decoded once (collective; errors agreed on). */
i2m_err_t i2m_dist_image_read(const i2m_par_t *par, const char *path, const i2m_image_read_opts_t *opts,
                              i2m_image_t **out);

/** The distance transform of @p img on every rank, each rank computing a share of it
 *  (collective; with one process, i2m_edt_create).  Errors are agreed on. */
i2m_err_t i2m_dist_edt_create(const i2m_par_t *par, const i2m_image_t *img, i2m_edt_t **out);

/** Options of the distributed run. */
typedef struct {
  i2m_threads_opts_t threads; /**< per process: threads, coarse factor, pinning, deterministic, depth */
  const char *trace;          /**< a file of one line per task (rank 0 writes it), or NULL */
  int inject_failure;         /**< tests: the rank that fails in the middle of refinement (-1: none) */
  bool spread_output;         /**< spread the output tets evenly over the ranks (i2m_dist_balance): when
                                   each rank writes its own piece; a file stitched on rank 0 gains
                                   less from it than the cells' move costs */
} i2m_dist_opts_t;

/** One rank's figures (the paper's Fig. 7 breakdown and the traffic). */
typedef struct {
  double preprocess;      /**< reading, distance transform, coarse mesh and its distribution (s) */
  double meshing;         /**< its worker threads refining (s) */
  double comm;            /**< fetching submeshes, packing and unpacking them, asking for tasks (s) */
  double idle;            /**< waiting for a task: nothing could run (s) */
  /** The master's seconds in each kind of communication work: waiting for the submeshes a
   *  task needs, packing submeshes for others (also while its threads refine: that time is not
   *  in comm), joining those that came, dropping those that left, and merging what a task made
   *  into the tiles' lists.  Where the communication figure goes, to drive it down. */
  double wait_data, pack, unpack, drop, merge;
  int64_t tasks, wide_tasks;
  int64_t skipping_tasks;       /**< tasks that went without some sides of their block */
  int64_t tiles_in, tiles_out;  /**< submeshes received and sent */
  int64_t bytes_in, bytes_out;
  int64_t answered_while_refining; /**< submeshes sent while its threads refined */
  int64_t insertions, removals;
  int64_t tets;           /**< tets it holds at the end (all labels) */
  int64_t peak_tets;      /**< the most it held at once (all labels) */
  double peak_rss;        /**< bytes */
} i2m_rank_figures_t;

typedef struct {
  int ranks, depth;
  bool deterministic;
  double fine_seconds;         /**< the distributed phase, wall clock */
  i2m_rank_figures_t *rank;    /**< owned: [ranks] (gathered on every rank) */
  int64_t tasks, wide_tasks, bytes, tiles_moved;
  /* i2m_dist_balance (after the tasks, again after a sliver pass): cells moved, their bytes,
   * the most output tets a rank held before the first and after the last, as a multiple of
   * the mean, and the steps' wall clock */
  int balance_calls;
  int64_t balance_cells, balance_bytes;
  double balance_before, balance_after, balance_seconds;
} i2m_dist_report_t;

/** The distributed refinement of r (every rank made it from the same image and parameters):
 *  the coarse mesh on rank 0's threads, then the tasks on every rank's threads, then the
 *  component rule; each rank ends with the tets of the cells it holds.  Collective. */
i2m_err_t i2m_dist_refine(const i2m_par_t *par, i2m_refine_t *r, const i2m_dist_opts_t *o, i2m_threads_report_t *team,
                          i2m_dist_report_t *rep);
void i2m_dist_report_free(i2m_dist_report_t *rep);

/** The sliver perturbation (i2m_refine_perturb_slivers) of the distributed mesh: the octree's
 *  cells with slivers as tasks, one pass over them per round (a task treats its cell's slivers
 *  inside its zone, the worst first, then in up to 4 rounds of its own the slivers it made
 *  there), rounds while moves are kept (after the first, with more targets and, until one
 *  keeps nothing, only the tasks whose block a rank holds), then the same with the too wide
 *  angles; every kept move
 *  passes every refinement rule.  *st: the whole mesh's figures.  Collective (after
 *  i2m_dist_refine). */
i2m_err_t i2m_dist_perturb_slivers(const i2m_par_t *par, i2m_refine_t *r, const i2m_dist_opts_t *o, double bound,
                                   i2m_sliver_stats_t *st);

/** The output tets spread over the ranks (src/dist/balance.c; after the tasks, before the
 *  pieces are first built, and after a sliver pass): whole cells move, from the most loaded
 *  rank to a neighbouring one, until none holds more than 5% above the mean (or no cell can
 *  move without the receiver passing the giver); the Location array and the labels across
 *  the faces follow.  rep (may be NULL) adds up the figures.  Collective; nothing at one
 *  rank. */
i2m_err_t i2m_dist_balance(const i2m_par_t *par, i2m_refine_t *r, i2m_dist_report_t *rep);

/** The labels across the faces between ranks (each rank tells the holder of the cell across
 *  each of its faces of another rank's the label of its tet there; the holders from the
 *  Location array kept in r).  Again after labels change.  Collective. */
i2m_err_t i2m_dist_exchange_ghosts(const i2m_par_t *par, i2m_refine_t *r);

/** The pieces of the whole mesh (src/dist/pieces.c): each rank's parts, joined across the
 *  faces between ranks, resolved on rank 0 (fragments, splits of components of at least
 *  @p min_voxels) and set in every rank's r (i2m_refine_groups then answers).  Collective. */
i2m_err_t i2m_dist_pieces(const i2m_par_t *par, i2m_refine_t *r, int64_t min_voxels);

/** The component rule's points for the pieces set by i2m_dist_pieces: every rank's claims on
 *  rank 0, the points from there to every rank, each filed by the rank that holds its cell;
 *  *filed_total: how many (0: no component is split).  Collective. */
i2m_err_t i2m_dist_bridge_points(const i2m_par_t *par, i2m_refine_t *r, int round, int64_t *filed_total);

/** The refinement counters of the whole run: sums over the ranks (the figures that are the
 *  whole mesh's already, fragments and rounds, stay).  Collective. */
void i2m_dist_sum_stats(const i2m_par_t *par, i2m_refine_stats_t *s);

/** The pieces (each rank's mesh, with global vertex ids) stitched on rank 0, one rank's after
 *  another, vertices merged by global id (the same place, or an error): on rank 0 *m becomes
 *  the whole mesh (without global ids); the other ranks' are unchanged.  Collective. */
i2m_err_t i2m_dist_gather_mesh(const i2m_par_t *par, i2m_tetmesh_t **m);

/** The quality figures of the whole mesh from each rank's of its piece (extremes, counts,
 *  histogram and per-label sums), on every rank.  Collective. */
void i2m_dist_reduce_quality(const i2m_par_t *par, i2m_quality_t *q);

#ifdef __cplusplus
}
#endif
#endif
