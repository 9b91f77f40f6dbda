/* i2m refine layer (layer 4): Delaunay refinement of a label image with the PI2M/PODM rules
 * (ARCHITECTURE §4), starting from the virtual box:
 *
 *   R1  ball of t meets an interface          -> closest interface point z (surface vertex),
 *                                                unless a surface vertex lies within delta of z
 *   R2  ball meets an interface, r >= 2 delta  -> circumcentre
 *   R3  t inside, r / shortest edge > ratio    -> circumcentre
 *   R4  t inside, r > size(circumcentre)       -> circumcentre
 *   R5  restricted facet, planar angle < 30°   -> surface centre (surface vertex)
 *   R6  restricted facet, a non-surface vertex -> surface centre (surface vertex)
 *   R7  after a surface vertex z               -> remove the free vertices within 2 delta of z
 *
 * Surface rules first, then R2, then the volume rules.  The mesher works in the image's grid
 * frame (image.h); extraction maps to world coordinates.  All rule evaluation goes through
 * a per-thread worker, so the threads layer runs the same code on many threads. */
#ifndef I2M_REFINE_H
#define I2M_REFINE_H

#include "i2m/dt.h"
#include "i2m/edt.h"
#include "i2m/image.h"
#include "i2m/quality.h"
#include "i2m/tetmesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/** A critical region: a world-coordinate box with its own size and ratio bounds. */
typedef struct {
  double lo[3], hi[3]; /**< world (LPS) corners, lo < hi */
  double size;         /**< max circumradius inside (mm) */
  double ratio;        /**< radius-edge bound inside */
} i2m_region_t;

/** A size bound for the tets of one label. */
typedef struct {
  int64_t value; /**< original label value */
  double size;   /**< max circumradius (mm) */
} i2m_label_size_t;

/** Refinement parameters (lengths in mm). */
typedef struct {
  double delta;       /**< surface sampling distance; <= 0: default from the spacing */
  double ratio;       /**< radius-edge bound (>= 2) */
  double facet_angle; /**< minimum planar angle of interface triangles, degrees (<= 30) */
  double size;        /**< max circumradius everywhere (INFINITY: none) */
  int nlabel_sizes;
  const i2m_label_size_t *label_sizes; /**< borrowed */
  int nregions;
  const i2m_region_t *regions;         /**< borrowed; world coordinates */
  uint64_t seed;
  /** The mesh frame: the image handed to refinement has its origin moved by -shift, the mesh
   *  is made there (its points snapped, i2m_dt_set_shift) and extracted in the world, shifted
   *  back exactly.  Zero by default (i2m_image_mesh_shift chooses it). */
  double shift[3];
} i2m_refine_params_t;

/** Default parameters (delta chosen by i2m_refine_default_delta at setup). */
void i2m_refine_params_default(i2m_refine_params_t *p);

/** The default delta for an image: max(0.8 x the smallest spacing, 0.5 x the largest).
 *  The surface is then sampled about 1.25 times per voxel along the finest axis (so
 *  one-voxel features and thin layers are followed and per-label volumes stay within a few
 *  percent), but never finer than half the slice spacing of an anisotropic image, whose
 *  staircase steps are that high anyway. */
double i2m_refine_default_delta(const i2m_image_t *img);

/** The size of a run, estimated from the image and the parameters before it starts. */
typedef struct {
  double delta;         /**< the delta in use (the default one when the parameters leave it) */
  double interface_mm2; /**< area of the voxel faces between labels (the staircase) */
  double volume_mm3;    /**< labelled volume */
  double tets;          /**< estimated output tets (within a factor of about two) */
  double bytes;         /**< estimated peak memory of a one-process run */
} i2m_refine_estimate_t;
/** Fills *e; one pass over the voxels (OpenMP threads). */
void i2m_refine_estimate(const i2m_image_t *img, const i2m_refine_params_t *p, i2m_refine_estimate_t *e);

/** Checks parameters against the image; one clear message on error. */
/** The checks that need only the image's geometry (its header): bounds on the parameters,
 *  delta against the image's extent, regions inside it.  I2M_ERR_ARG names the option. */
i2m_err_t i2m_refine_params_check_geometry(const i2m_refine_params_t *p, const i2m_image_t *img);
i2m_err_t i2m_refine_params_check(const i2m_refine_params_t *p, const i2m_image_t *img);

/** Counters of what refinement did. */
typedef struct {
  int64_t rule[8];        /**< insertions per rule (index 1..6), removals at [7] */
  int64_t insertions, removals, rollbacks;
  int64_t failed;         /**< bad elements dropped because their point could not go in */
  int64_t duplicates;     /**< points that coincided with a vertex */
  int64_t junction_skips; /**< R5 skipped near junctions of three or more labels */
  int64_t tets_created;
  int64_t deferred;       /**< deterministic mode: elements left to the sequential pass */
  int64_t judged;         /**< dist: elements handed to another subregion, dropped as having nothing to do */
  int64_t bridges;        /**< free vertices the component rule inserted (R8, i2m_refine_bridge_splits) */
  int64_t bridge_rounds;  /**< rounds of the component rule that found a split */
  int64_t fragments;      /**< fragments relabelled (i2m_refine_repair_fragments) */
  int64_t fragment_tets;  /**< their tets */
  double seconds;
} i2m_refine_stats_t;

/** Result of one refinement step of a worker. */
enum {
  I2M_STEP_IDLE = 0,     /**< nothing to do: the worker's lists are empty */
  I2M_STEP_DONE = 1,     /**< an element was treated (or found stale) */
  I2M_STEP_ROLLBACK = 2, /**< another thread holds a vertex; the element went back to the list */
  I2M_STEP_FULL = 3,     /**< the reserved capacity is exhausted; grow, then retry */
  I2M_STEP_ERROR = -1    /**< an error (message set) */
};

typedef struct i2m_refine i2m_refine_t;
typedef struct i2m_refine_worker i2m_refine_worker_t;

/** Sets up refinement of @p img: the virtual box triangulation with every tet classified.
 *  @p img and @p edt are borrowed and must outlive the object. */
i2m_err_t i2m_refine_create(const i2m_image_t *img, const i2m_edt_t *edt, const i2m_refine_params_t *params,
                            i2m_refine_t **out);
void i2m_refine_destroy(i2m_refine_t **r);

/** Runs refinement to completion on the calling thread. */
i2m_err_t i2m_refine_run(i2m_refine_t *r);

/** The triangulation being refined (borrowed). */
i2m_dt_t *i2m_refine_dt(i2m_refine_t *r);
/** The parameters in use (delta resolved). */
const i2m_refine_params_t *i2m_refine_params(const i2m_refine_t *r);
/** Statistics summed over the workers. */
void i2m_refine_get_stats(const i2m_refine_t *r, i2m_refine_stats_t *s);

/** What the sliver perturbation did (i2m_refine_perturb_slivers). */
typedef struct {
  int64_t slivers_before, slivers_after; /**< output tets below the bound */
  double min_before, min_after;          /**< smallest dihedral angle of the output tets (degrees) */
  int64_t tried, kept;                   /**< moves (and insertions) tried and kept */
  int64_t inserted;                      /**< of the kept: points inserted (new vertices) */
  int64_t removed;                       /**< of the kept: vertices removed (none in their place) */
  double seconds;
  i2m_dihedral_bands_t bands_before;     /**< this process's output tets' dihedral bands before */
} i2m_sliver_stats_t;

/** Sliver perturbation, after refinement and before extraction (no other work on the mesh):
 *  for the output tets whose smallest dihedral angle is below @p bound degrees, worst first,
 *  inserts a point at the circumcentre (on the closest interface point when that is within
 *  delta), else moves their vertices (surface vertices along their own interface patch),
 *  keeping a change only when every changed tet passes the refinement rules and the changed
 *  output tets' smallest angle beats the sliver's (an insertion) or the vertex's old star's (a
 *  move), so every guarantee of refinement holds.  On the calling
 *  thread; i2m_threads_perturb_slivers runs the same work, with the same result, on threads. */
i2m_err_t i2m_refine_perturb_slivers(i2m_refine_t *r, double bound, i2m_sliver_stats_t *st);

/* ---- for the threads layer: several workers on one triangulation ---- */

/** Replaces the single worker by @p n workers (n >= 1; n > 1 lock vertices), moving the
 *  bad elements found so far to worker 0; makes room for growth.  Not while refining. */
i2m_err_t i2m_refine_set_workers(i2m_refine_t *r, int n);
int i2m_refine_nworkers(const i2m_refine_t *r);
/** One step of worker k (thread safe across different k): an I2M_STEP_* value. */
int i2m_refine_step(i2m_refine_t *r, int k);
/** After I2M_STEP_ERROR: its error code (the message is set in the thread that made the step). */
i2m_err_t i2m_refine_step_error(const i2m_refine_t *r, int k);
/** After I2M_STEP_ROLLBACK: the worker index (0-based) that held the lock, or -1. */
int i2m_refine_conflict_worker(const i2m_refine_t *r, int k);
/** Bad elements and pending removals of worker k. */
size_t i2m_refine_backlog(const i2m_refine_t *r, int k);
/** Moves about half of worker from's backlog to worker to (to must be idle); returns the
 *  number moved. */
size_t i2m_refine_give(i2m_refine_t *r, int from, int to);
/** Spreads worker 0's backlog over all workers by position (slabs along the longest axis),
 *  so that threads start in different places.  Not while refining. */
i2m_err_t i2m_refine_spread(i2m_refine_t *r);
/** Grows the triangulation's capacity (every worker paused). */
i2m_err_t i2m_refine_grow(i2m_refine_t *r);
/** Multiplies delta and every size bound by f (the coarse phase uses f > 1; 1 restores the
 *  parameters).  Not while refining. */
void i2m_refine_set_scale(i2m_refine_t *r, double f);
/** Worker k of n classifies the live tets k, k+n, ... and queues the bad ones (after a change
 *  of bounds; all n workers run it, nothing else runs). */
i2m_err_t i2m_refine_reclassify(i2m_refine_t *r, int k, int n);
/** Statistics of worker k. */
void i2m_refine_worker_stats(const i2m_refine_t *r, int k, i2m_refine_stats_t *s);
/** Returns the workers' pooled slots to the triangulation (after a parallel phase). */
void i2m_refine_sync(i2m_refine_t *r);

/* ---- for the threads layer: the deterministic mode (the same mesh on any number of
 * threads; see src/refine/tiles.c).  Every call not marked thread safe runs alone. ---- */

/** From now on every tet centred in the labelled block whose radius exceeds half the fine
 *  tiles' margin is split, whatever its label (as the paper's coarse mesh bounds all sizes):
 *  cavities then fit the zones, and few elements wait for a sequential pass. */
void i2m_refine_tiling_bound(i2m_refine_t *r);
/** Cuts the labelled block into tiles for the current scale and moves every queued element
 *  into its tile (workers stop taking vertex locks). */
i2m_err_t i2m_refine_tiling_begin(i2m_refine_t *r);
/** Sets the octree's depth (2^depth cells along each axis of the labelled block): the tiles
 *  of i2m_refine_octree_begin, and the background bound (it calls i2m_refine_tiling_bound). */
void i2m_refine_set_depth(i2m_refine_t *r, int depth);
/** The octree's depth when none is asked for: as deep as gives @p workers (ranks x threads)
 *  several tasks of each colour (workers <= 0: 3, the deterministic mode's, which must not
 *  depend on them), but never cells shorter than 16 delta along an axis, and at least 1 (2
 *  for more than one worker). */
int i2m_refine_default_depth(const i2m_refine_t *r, int workers);
/** The depth set (-1: none). */
int i2m_refine_depth(const i2m_refine_t *r);
/** The same as i2m_refine_tiling_begin with the octree's cells as tiles: 27 colours, each
 *  tile's task holding the 27 cells around it (ctx->block), a wide task per tile for what its
 *  zone cannot hold, the same global ids on every rank. */
i2m_err_t i2m_refine_octree_begin(i2m_refine_t *r);
/** The number of colours of the tiling's phases (8 or 27). */
int i2m_refine_tiling_colors(const i2m_refine_t *r);
/** Octree: the tiles whose wide task has work, in order (borrowed until the next call). */
i2m_err_t i2m_refine_tiling_wide_tiles(i2m_refine_t *r, const uint32_t **tiles, uint32_t *ntiles);
/** Octree: worker k runs tile id's wide task (alone: slots granted here; merge after). */
i2m_err_t i2m_refine_tile_run_wide(i2m_refine_t *r, int k, uint32_t id);
/** Octree: an error naming the count if elements that no task could do are still bad. */
i2m_err_t i2m_refine_tiling_check_stuck(i2m_refine_t *r);
/** Frees the tiles (their unused slots go back to the triangulation).  Accepts none. */
void i2m_refine_tiling_end(i2m_refine_t *r);
/** After a change of bounds: every tet classified again into the tiles, in three steps:
 *  prepare; worker k of n classifies its share of the slots (thread safe across k); collect. */
i2m_err_t i2m_refine_tiling_prepare_classify(i2m_refine_t *r);
i2m_err_t i2m_refine_tiling_classify(i2m_refine_t *r, int k, int n);
i2m_err_t i2m_refine_tiling_collect(i2m_refine_t *r);
/** Is there anything left to do? */
bool i2m_refine_tiling_has_work(const i2m_refine_t *r);
/** The tiles of colour @p color (0..7) with work, busiest first, each with slots granted;
 *  *tiles is borrowed until the next call. */
i2m_err_t i2m_refine_tiling_phase(i2m_refine_t *r, int color, const uint32_t **tiles, uint32_t *ntiles);
/** Worker k refines tile id until its lists are empty or its slots run out (thread safe
 *  across different k and tiles of one phase). */
i2m_err_t i2m_refine_tile_run(i2m_refine_t *r, int k, uint32_t id);
/** The barrier after a phase: hand-overs reach their tiles, in an order of their own. */
i2m_err_t i2m_refine_tiling_merge(i2m_refine_t *r);
/** The end of a round: worker 0 does, in order, what no tile could (coarse tiles: no zone;
 *  octree: the wide tasks, one at a time). */
i2m_err_t i2m_refine_tiling_sequential(i2m_refine_t *r);
/** Tile side (mm), rounds and sequential operations so far (0 without a tiling). */
void i2m_refine_tiling_figures(const i2m_refine_t *r, double *side, int64_t *rounds, int64_t *sequential_ops);

/* ---- for the dist layer: submeshes (src/refine/submesh.c).  A rank holds some tiles of the
 * octree; everything here runs alone on the rank (no task running), except i2m_refine_pack. */

/** Starts the bookkeeping on the octree's tiles (i2m_refine_octree_begin first): the tiles'
 *  lists of tets, the id map of the vertices, the faces of other ranks.  hold_all: this rank
 *  holds every tile (rank 0 after the coarse mesh), else none. */
i2m_err_t i2m_refine_dist_begin(i2m_refine_t *r, bool hold_all);
void i2m_refine_dist_end(i2m_refine_t *r);
/** Asynchronous mode (on) or the deterministic one: each task drops the elements it hands to
 *  other tiles that have nothing to do (judged in its block), so that they draw no task that
 *  would fetch data for them; and it is granted slots for a good part of its work at once
 *  (16 a bad element), so that it does not end, report and get its cell back several times. */
void i2m_refine_dist_asynchronous(i2m_refine_t *r, bool on);
/** After tasks: the tets and vertices they made, filed in their tiles and in the id map. */
i2m_err_t i2m_refine_dist_merge(i2m_refine_t *r);
/** Does this rank hold tile id? */
bool i2m_refine_holds(const i2m_refine_t *r, uint32_t id);
/** Tile id's submesh as a buffer (*buf owned by the caller): its tets, their vertices with
 *  global ids, the cells across its outer faces, its bad elements and its state.  Reads only
 *  the tile's tets and vertices: may run while tasks run on blocks without this tile. */
i2m_err_t i2m_refine_pack(i2m_refine_t *r, uint32_t id, void **buf, size_t *len);
/** Tiles ids[0..n) leave: their tets and the vertices no local tet uses any more; the faces of
 *  the local tets next to them become another rank's.  (Several at once: the vertices that
 *  need another local tet find it in one pass over the remote faces.) */
i2m_err_t i2m_refine_drop(i2m_refine_t *r, const uint32_t *ids, uint32_t n);
/** The output tets (alive, labelled) of tile id that this rank holds, into *n (its list
 *  cleared of stale entries on the way; 0 for a tile held elsewhere). */
i2m_err_t i2m_refine_tile_kept_tets(i2m_refine_t *r, uint32_t id, int64_t *n);
/** A submesh arrives: joined to the local tets by matching faces on global ids.  *tile (may be
 *  NULL) gets its tile. */
i2m_err_t i2m_refine_unpack(i2m_refine_t *r, const void *buf, size_t len, uint32_t *tile);
/** Before tile id's task: its pending removals whose vertex was not here when they arrived. */
void i2m_refine_dist_resolve(i2m_refine_t *r, uint32_t id);
/** Before a job of tiles (run by i2m_refine_tile_run, then i2m_refine_tiling_merge): their
 *  lists without stale entries, their slots granted, the grids' room made. */
i2m_err_t i2m_refine_tiles_prepare(i2m_refine_t *r, const uint32_t *tiles, uint32_t n);
/** Tile id's figures (I2M_TILE_NFIG of them): fig[0] its live bad elements and bridge points
 *  (its task's work), fig[1] its wide task's, fig[2] about how many tets it holds (its list's
 *  entries, some stale), fig[3] its bridge points, fig[4] those left to its wide task, fig[5]
 *  the sides of the cell its task may go without (asynchronous mode, see i2m_refine_tile_skip;
 *  else 0) (its lists are cleared of stale entries). */
#define I2M_TILE_NFIG 6
void i2m_refine_tile_figures(i2m_refine_t *r, uint32_t id, int64_t fig[I2M_TILE_NFIG]);
/** Tile id's next task goes without the neighbours beyond the sides in skip (bit 2a: lower
 *  along axis a, 2a + 1: higher; 0: the whole block): its zone stops I2M_SKIP_MARGIN deltas
 *  short of those sides, and what it cannot do stays in its lists for a task of the whole
 *  block (not its wide task).  The dist layer's asynchronous mode: a task of a few elements
 *  near one side fetches the cells there, not its whole block. */
#define I2M_SKIP_MARGIN 3.0
void i2m_refine_tile_skip(i2m_refine_t *r, uint32_t id, unsigned skip);
/** The tiling's cells along each axis. */
void i2m_refine_tiling_cells(const i2m_refine_t *r, int32_t n[3]);

/** The Location array (the rank that holds each tile; [ntiles]), kept for the collective steps
 *  after the tasks (pieces, labels across faces); NULL before it is set. */
i2m_err_t i2m_refine_dist_set_location(i2m_refine_t *r, const int32_t *holder);
const int32_t *i2m_refine_dist_location(const i2m_refine_t *r);

/** A face of another rank's: its sorted global ids, the cell across it, a label index (the
 *  local tet's, when sent; the one across, when received). */
typedef struct {
  i2m_gidx_t key[3];
  int32_t cell;
  uint16_t label;
} i2m_face_label_t;
/** The faces of local tets whose other side another rank holds: how many, and each with the
 *  cell across and the local tet's label (out: room for i2m_refine_dist_nfaces). */
size_t i2m_refine_dist_nfaces(const i2m_refine_t *r);
void i2m_refine_dist_faces(const i2m_refine_t *r, i2m_face_label_t *out);
/** The labels of the tets across such faces, as the ranks across sent them; returns how many
 *  named a face this rank does not have (0 when the ranks agree). */
int64_t i2m_refine_dist_ghosts(i2m_refine_t *r, const i2m_face_label_t *faces, size_t n);

/* ---- for the threads layer: the sliver perturbation on the tiles (src/refine/slivers.c);
 * every call not marked thread safe runs alone ---- */

/** Lists the slivers and cuts the block into tiles (the workers stop taking locks). */
i2m_err_t i2m_refine_slivers_begin(i2m_refine_t *r, double bound);
/** Is another round worth it (slivers left, the last round kept a move, rounds left)? */
bool i2m_refine_slivers_has_work(const i2m_refine_t *r);
/** The tiles of colour @p color (0..7) with slivers this round, each with slots granted. */
i2m_err_t i2m_refine_slivers_phase(i2m_refine_t *r, int color, const uint32_t **tiles, uint32_t *ntiles);
/** Worker k treats tile id's slivers inside its zone (thread safe across different k and
 *  tiles of one phase). */
i2m_err_t i2m_refine_tile_slivers(i2m_refine_t *r, int k, uint32_t id);
/** The barrier after a phase: the tiles' unused slots go back. */
i2m_err_t i2m_refine_slivers_merge(i2m_refine_t *r);
/** The end of a round: worker 0 treats, in order, the slivers no zone could hold. */
i2m_err_t i2m_refine_slivers_sequential(i2m_refine_t *r);
/** Counts what is left, frees the tiles; *st (may be NULL) gets the figures.  Accepts a pass
 *  that failed. */
i2m_err_t i2m_refine_slivers_end(i2m_refine_t *r, i2m_sliver_stats_t *st);

/* ---- for the dist layer: the sliver perturbation on the octree's tiles, as tasks.  A task
 * (i2m_refine_tile_slivers, after i2m_refine_slivers_dist_prepare) finds its tile's slivers
 * in the tile's own tets and treats them inside its zone; rounds and stages are the dist
 * layer's.  The figures of *st are this rank's (the dist layer sums them). ---- */
i2m_err_t i2m_refine_slivers_dist_begin(i2m_refine_t *r, double bound);
/** The bound of this stage (degrees), the round (it seeds the moves) and whether it is wide
 *  (more targets, farther: after a round that kept no move). */
void i2m_refine_slivers_dist_round(i2m_refine_t *r, double bound, int round, bool wide);
/** The last stage from now on: the output tets with a dihedral angle wider than
 *  180 - 4/3 x the final bound are treated too (160 degrees at 15), and a change is kept only
 *  when its output tets are within both bounds (one process: after the other stages, by
 *  itself). */
void i2m_refine_slivers_caps(i2m_refine_t *r);
/** Slivers of tile id now (below the stage's bound). */
int64_t i2m_refine_tile_sliver_count(i2m_refine_t *r, uint32_t id);
/** Before a job of sliver tasks: slots granted, the grids' room made. */
i2m_err_t i2m_refine_slivers_dist_prepare(i2m_refine_t *r, const uint32_t *tiles, uint32_t n);
/** Moves tried and kept so far on this rank. */
void i2m_refine_slivers_dist_moves(const i2m_refine_t *r, int64_t *tried, int64_t *kept);
i2m_err_t i2m_refine_slivers_dist_end(i2m_refine_t *r, i2m_sliver_stats_t *st);

/** After refinement: frees the spatial grids and the workers' scratch (extraction, stats and
 *  parameters stay usable; the transform is asked only by i2m_refine_repair_fragments). */
void i2m_refine_release_scratch(i2m_refine_t *r);
/** After extraction: frees the triangulation too (stats and parameters stay usable). */
void i2m_refine_release_mesh(i2m_refine_t *r);


/** Image components of at least this many voxels must come out whole (one piece of tets). */
#define I2M_WHOLE_MIN_VOXELS 10000

/** Rounds of the component rule (bridges, then refinement) at most. */
#define I2M_BRIDGE_ROUNDS 6

/* ---- pieces of the labelled mesh (src/refine/pieces.c).  A piece is a face-connected set of
 * kept tets of one label.  Each process finds the parts of its own tets (pieces of its local
 * mesh); the dist layer joins parts across the faces between ranks; i2m_pieces_resolve turns
 * every part into the pieces of the whole mesh (groups), the same on any number of ranks and
 * threads.  On one process, the calls below that need groups resolve the local parts. ---- */

/** A part: its least tet (the sorted global ids, a key no order of work changes), tets,
 *  volume, label; small: at most 64 tets (a fragment's size). */
typedef struct {
  i2m_gidx_t key[4];
  double volume;
  int64_t ntets;
  uint16_t label;
  bool small;
} i2m_part_t;

/** The volume of a part whose tets' circumcentres lie in one image component (root run of
 *  the image's 6-connected components), and its least tet there. */
typedef struct {
  i2m_gidx_t key[4];
  double volume;
  int64_t comp;
  uint32_t part;
  uint32_t seed; /* (the local slot of that tet) */
} i2m_part_comp_t;

/** The face area a small part shares with another label (0: outside the mesh). */
typedef struct {
  double area;
  uint32_t part;
  uint16_t label;
} i2m_part_area_t;

/** A face of a part whose other side another rank holds. */
typedef struct {
  i2m_gidx_t key[3]; /* the face's sorted global ids */
  int32_t cell;      /* the cell of the tet across it */
  uint32_t part;
  uint16_t label;
} i2m_part_face_t;

/** The parts of one process (borrowed from r), or of every rank (gathered).  pairs: parts
 *  of this process that are one piece although they are not one part (after the fragments'
 *  repair joined them: local indices, two per pair). */
typedef struct {
  size_t nparts, ncomps, nareas, nfaces;
  i2m_part_t *part;
  i2m_part_comp_t *comp;
  i2m_part_area_t *area;
  i2m_part_face_t *face;
  size_t npairs;
  const int64_t *pairs;
} i2m_parts_t;

/** A piece of the whole mesh: one or more parts joined across ranks. */
typedef struct {
  i2m_gidx_t key[4];   /**< its least tet */
  i2m_gidx_t seed[4];  /**< its least tet whose circumcentre lies in its component */
  double volume, comp_volume; /**< its volume, and of it in its component */
  int64_t ntets;
  int64_t comp;        /**< the image component that holds the circumcentres of most of its volume (-1: none) */
  int32_t relabel;     /**< a fragment: the label index it takes (-1: none) */
  uint16_t label;
} i2m_group_t;

/** A large image component that two or more pieces (not fragments) stand for. */
typedef struct {
  int64_t comp;
  uint16_t label;
  uint32_t ngroups;
  int64_t *groups; /**< owned: the pieces, the largest first (ties: the least key) */
} i2m_split_t;

/** The pieces of the whole mesh. */
typedef struct {
  size_t ngroups, nparts, nsplits;
  i2m_group_t *group;   /**< owned: [ngroups] */
  int64_t *part_group;  /**< owned: [nparts] the group of each part (of the parts resolved, or this rank's) */
  i2m_split_t *split;   /**< owned: [nsplits] */
  int64_t fragments, fragment_tets;
} i2m_pieces_global_t;

/** This process's parts (borrowed: valid until the mesh or a label changes). */
i2m_err_t i2m_refine_parts(i2m_refine_t *r, i2m_parts_t *out);
/** The pieces of the whole mesh from every part (indices into all->part), joined where pairs
 *  (npairs pairs of part indices) say two parts meet across a face; fragments decided
 *  (relabel); splits of components of at least min_voxels listed.  Pure: the same on every
 *  rank that has the same input. */
i2m_err_t i2m_pieces_resolve(const i2m_refine_t *r, const i2m_parts_t *all, const int64_t *pairs, size_t npairs,
                             int64_t min_voxels, i2m_pieces_global_t *G);
void i2m_pieces_global_free(i2m_pieces_global_t *G);
/** The dist layer's result for this rank (G->part_group: this rank's parts), moved into r
 *  (G is emptied). */
i2m_err_t i2m_refine_set_groups(i2m_refine_t *r, i2m_pieces_global_t *G);
/** Dist: the part of the local kept tet of label @p label on the face with these sorted global
 *  ids whose other side is another rank's, or -1 (no such face here, or another label). */
int64_t i2m_refine_part_at_face(i2m_refine_t *r, const i2m_gidx_t key[3], uint16_t label);
/** Are the pieces of the whole mesh in r those of the mesh as it is (1) or not (0)? */
int i2m_refine_groups_valid(const i2m_refine_t *r);
/** The pieces of the whole mesh: set by the dist layer, or resolved from this process's parts
 *  (borrowed, as i2m_refine_parts). */
i2m_err_t i2m_refine_groups(i2m_refine_t *r, int64_t min_voxels, const i2m_pieces_global_t **out);

/** After refinement: gives every fragment the label it shares the most face area with (0:
 *  it leaves the mesh).  A fragment is a piece of one label of at most 64 tets and less than
 *  27 voxels of volume, inside a component of the image (6-connected voxels of that label) of
 *  at least 64 voxels of which it holds less than an eighth: a bit of a larger region left
 *  apart from it where the region narrows below delta, floating or hanging by an edge (a
 *  loose body or a hinge in a finite-element model).  Specks the image really has stay.
 *  Interface triangles are only removed or relabelled, so every guarantee holds.  Uses the
 *  transform (still alive) and the groups (i2m_refine_groups); the same result on any number
 *  of threads and ranks; counted in the stats. */
i2m_err_t i2m_refine_repair_fragments(i2m_refine_t *r);

/* ---- the component rule (R8, src/refine/bridges.c) ---- */

/** A voxel of a split component whose centre lies in a local tet: the split (index in
 *  G->split), the voxel (box index of the transform), its class: the position of the tet's
 *  piece in the split's list, or I2M_CLAIM_GAP (another label, outside, a fragment). */
typedef struct {
  int64_t voxel;
  int32_t split;
  int32_t cls;
} i2m_voxel_claim_t;
#define I2M_CLAIM_GAP INT32_MAX

/** A free vertex of the component rule, with the global id it gets on every rank. */
typedef struct {
  double x[3];
  i2m_gidx_t gid;
} i2m_bridge_point_t;

/** The claims of the voxels of every split in G by the local tets (*out owned). */
i2m_err_t i2m_refine_split_claims(i2m_refine_t *r, const i2m_pieces_global_t *G, i2m_voxel_claim_t **out, size_t *n);
/** The bridge points from every rank's claims (sorted in place; where two claim a voxel the
 *  lower class wins): for each piece of a split but the largest, a 0-1 breadth-first search
 *  over the component's voxels finds the path to another of its pieces that crosses the
 *  fewest gap voxels; a point at the centre of each gap voxel, and of each voxel face where
 *  the path passes from one class to another.  Pure; round numbers the global ids. */
i2m_err_t i2m_bridge_points(const i2m_refine_t *r, const i2m_pieces_global_t *G, i2m_voxel_claim_t *claims,
                            size_t nclaims, int round, i2m_bridge_point_t **out, size_t *np);
/** One process: inserts the points now (worker 0; on the octree's tiles in the order the
 *  ranks' tasks insert them, colour by colour and tile by tile, else in the list's order; their
 *  tets queued for refinement, in the tiles if a tiling is in place, then put in an order of
 *  their own). */
i2m_err_t i2m_refine_insert_bridges(i2m_refine_t *r, const i2m_bridge_point_t *p, size_t n, int64_t *inserted);
/** Dist layer: the points whose cell this rank holds become work of that cell's task (which
 *  inserts them first).  Returns through *filed how many.  Every rank calls it with every
 *  point (a round of the rule is counted). */
i2m_err_t i2m_refine_file_bridges(i2m_refine_t *r, const i2m_bridge_point_t *p, size_t n, int64_t *filed);

/** The component rule on one process, after refinement has run dry: the splits, their bridge
 *  points, inserted (i2m_refine_insert_bridges): refinement must run again, then this rule,
 *  until *inserted is 0.  *splits: the split components found.  Alone. */
i2m_err_t i2m_refine_bridge_splits(i2m_refine_t *r, int64_t min_voxels, int64_t *splits, int64_t *inserted);

/** Per label: how the image's 6-connected components come out in the mesh. */
typedef struct {
  int64_t value;            /**< original label value */
  int64_t image_components; /**< 6-connected components of its voxels */
  int64_t large_components; /**< of them, with at least the census's number of voxels */
  int64_t mesh_pieces;      /**< face-connected pieces of its tets in the mesh */
  int64_t split_components; /**< large components that two or more pieces (not fragments) stand for */
} i2m_label_pieces_t;

/** The census of every label's components and pieces from the pieces G; large components
 *  have at least @p min_voxels voxels.  *out (owned, [nlabels], by label index) is freed with
 *  i2m_free. */
i2m_err_t i2m_refine_census_of(i2m_refine_t *r, const i2m_pieces_global_t *G, int64_t min_voxels,
                               i2m_label_pieces_t **out);
/** After refinement (and the fragments' repair): the census from i2m_refine_groups. */
i2m_err_t i2m_refine_census(i2m_refine_t *r, int64_t min_voxels, i2m_label_pieces_t **out);

/** The labelled mesh: tets whose circumcentre is inside, with their label value, and the
 *  interface triangles, in world coordinates, compacted.  Not collective. */
i2m_err_t i2m_refine_extract(const i2m_refine_t *r, i2m_tetmesh_t **out);

#ifdef __cplusplus
}
#endif
#endif
