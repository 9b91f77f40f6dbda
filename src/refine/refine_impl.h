/* Refine layer internals: the per-tet payload cached at creation, the bad-element lists, the
 * surface-vertex grid (for R1's spacing test), and the per-thread worker. */
#ifndef I2M_REFINE_IMPL_H
#define I2M_REFINE_IMPL_H

#include <math.h>
#include <stdatomic.h>

#include "i2m/geometry.h"
#include "i2m/predicates.h"
#include "i2m/refine.h"

/** Payload of every tet (kernel tpay), set when the tet is created: only the label at its
 *  circumcentre (2 bytes per tet); centre and radius are recomputed when needed. */
typedef struct {
  uint16_t label; /* label index at the circumcentre */
} tet_info_t;

static inline tet_info_t *tinfo(const i2m_dt_t *dt, uint32_t t) { return (tet_info_t *)i2m_dt_payload(dt, t); }

/** Does tet t belong to the output mesh (alive, labelled)? */
/* Tet t's vertex coordinates, in its order. */
static inline void tet_points(const i2m_dt_t *dt, uint32_t t, const double *x[4])
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (int i = 0; i < 4; i++) x[i] = i2m_dt_xyz(dt, v[i]);
}
static inline bool tet_kept(const i2m_dt_t *dt, uint32_t t) { return i2m_dt_alive(dt, t) && tinfo(dt, t)->label != 0; }

/** A tet's circumcentre (world), squared circumradius (INFINITY when flat), label, and the
 *  interface point closest to the centre (probe.d2 is +inf when it lies beyond the probe's
 *  reach, see tet_probe, or the tet is flat). */
typedef struct {
  double cc[3];
  double r2;
  int label;
  double u[3];  /* cc in the transform's voxel frame, where the probe starts (NaN: flat) */
  int64_t vox;  /* the voxel of the transform's box that holds u, or -1 (i2m_edt_voxel_k) */
  i2m_edt_probe_t probe;
} tet_geom_t;

/** A bad element: a tet, its meta when recorded (stale once the tet changes) and its
 *  vertices, which a thread locks before it reads anything of the tet. */
typedef struct {
  uint32_t t, meta;
  uint32_t v[4];
} bad_t;

/** A stack of bad elements.  The vertices are stored only when several threads share the
 *  mesh (wide lists): alone, a worker reads them from the mesh when it pops the element,
 *  and an entry takes 8 bytes instead of 24. */
typedef struct {
  uint32_t (*e)[2];    /* owned: [cap] t, meta */
  uint32_t (*v)[4];    /* owned: [cap] vertices (wide lists), else NULL */
  size_t n, cap;
  bool wide;
} badlist_t;

/** Priority levels: surface rules, R2, volume rules. */
enum { LEVEL_SURFACE = 0, LEVEL_R2 = 1, LEVEL_VOLUME = 2, NLEVELS = 3 };

/** What to do about a bad element. */
typedef struct {
  int rule;           /* 0: nothing; 1..6: the rule */
  int level;          /* the list it belongs to */
  double dist2;       /* squared distance from p to the nearest interface */
  double p[3];        /* the point to insert (world) */
  uint32_t seed;      /* a tet whose circumball holds p */
  uint8_t kind;       /* I2M_VK_SURFACE or I2M_VK_FREE */
  uint32_t patch;     /* surface points: the interface's label pair (patch_key) */
} action_t;

/** An interface patch: the unordered pair of label indices on its two sides. */
static inline uint32_t patch_key(int a, int b) { return a < b ? ((uint32_t)a << 16 | (uint32_t)b) : ((uint32_t)b << 16 | (uint32_t)a); }

/** A spatial hash of vertices: cells of side h, each a list through next[]; a tag per
 *  vertex.  Used for the surface vertices (tag: the interface patch; append-only, lock-free:
 *  a vertex is published by a compare-and-swap on its cell's head after its next and tag
 *  are written) and for the free vertices close to an interface (R7's candidates; inserts
 *  and removals take a striped spinlock when several threads run). */
#define VGRID_STRIPES 4096
#define VGRID_MEMBER 1u /* the free-vertex grid's tag of its members (0 once removed) */
typedef struct {
  double h, inv_h;          /* cell side and its inverse */
  double origin[3];         /* corner of cell (0,0,0) */
  uint32_t nc[3];           /* cells along each axis (points outside are clamped into the border) */
  uint32_t ncells;
  _Atomic uint32_t *head;   /* owned: [ncells] first vertex of each cell */
  _Atomic uint32_t *next;   /* owned: [cap_next] next vertex in the same cell */
  uint32_t *tag;            /* owned: [cap_next] the vertex's tag */
  uint32_t cap_next;
  _Atomic uint32_t *stripe; /* owned: [VGRID_STRIPES] spinlocks (NULL: sequential or lock-free) */
} vgrid_t;

/** A free vertex R7 wants removed; the global id tells a recycled slot apart. */
typedef struct {
  uint32_t v;
  i2m_gidx_t gid;
} pending_t;

/* ---- pieces of the labelled mesh (pieces.c) ---- */

#define PIECE_SMALL_TETS 64                 /* a fragment has at most this many tets (pieces_small_tets), */
#define PIECE_FRAGMENT_VOXELS 27.0          /* less than this many voxels of volume, */
#define PIECE_FRAGMENT_MIN_IMAGE_VOXELS 64  /* lies in an image component at least this large */
#define PIECE_FRAGMENT_SHARE 8.0            /* and holds less than 1/8 of it */
#define PIECE_SLIVER_GROWTH 4               /* (after a sliver pass: see pieces_small_tets) */

/** The parts of the local mesh (see i2m_parts_t), and the pieces of the whole mesh. */
typedef struct {
  _Atomic uint32_t *par; /* owned: [slots] each kept tet's part (pieces_index) */
  _Atomic uint32_t *idx; /* owned: [slots] scratch: each kept tet's image component (UINT32_MAX: none) */
  uint32_t *root;        /* owned: [nparts] each part's smallest slot */
  i2m_part_t *part;      /* owned: [nparts] in the order of their roots */
  i2m_part_comp_t *comp; /* owned: [ncomps] */
  i2m_part_area_t *area; /* owned: [nareas] */
  i2m_part_face_t *face; /* owned: [nfaces] */
  int64_t *pairs;        /* owned: [2 npairs] parts the fragments' repair joined (local indices) */
  size_t nparts, ncomps, nareas, nfaces, npairs;
  i2m_pieces_global_t global; /* the pieces of the whole mesh, when global_valid */
  bool global_valid;
} pieces_t;

/** The parts of the current labelled mesh (builds r->pieces_ic on first use). */
i2m_err_t pieces_build(i2m_refine_t *r, pieces_t *P);
/** The same, kept in r until the mesh or a label changes (pieces_invalidate): the component
 *  rule's last round, the fragments' repair and the census share one. */
i2m_err_t pieces_get(i2m_refine_t *r, pieces_t **out);
void pieces_invalidate(i2m_refine_t *r);
/** After the fragments took their labels: r->pieces made those of the relabelled mesh (the
 *  whole mesh's pieces to resolve again, on one process or across the ranks). */
i2m_err_t pieces_after_relabel(i2m_refine_t *r);
void pieces_free(pieces_t *P);
/** The index of kept tet t's part. */
uint32_t pieces_index(const pieces_t *P, uint32_t t);
/** Is this piece a fragment by its size and component (fragments.c gives it a neighbour's
 *  label unless it is its label's main piece)? */
bool pieces_group_is_fragment(const i2m_refine_t *r, const i2m_group_t *g);
/** A tet's key: its sorted global ids; keys compared lexicographically. */
void pieces_tet_key(const i2m_dt_t *dt, uint32_t t, i2m_gidx_t k[4]);
int pieces_key_cmp(const i2m_gidx_t a[4], const i2m_gidx_t b[4]);
double pieces_tet_volume(const i2m_dt_t *dt, uint32_t t);

/* ---- tiles (tiles.c): the deterministic mode's, and the octree subregions of the dist layer
 * (which the deterministic mode's fine phase shares, so that one process and many ranks make
 * the same mesh) ---- */

#define TILE_NONE UINT32_MAX

/** Where a hand-over goes at its target tile. */
enum { HAND_QUEUE = 0, HAND_WIDE = 1, HAND_STUCK = 2 };

/** An element handed over at the next barrier: to a tile's lists (to; where: HAND_QUEUE), to
 *  the sequential pass (to = TILE_NONE, coarse tiles), to its tile's wide task (HAND_WIDE:
 *  octree, it could not be done inside the zone) or to the elements no task could do
 *  (HAND_STUCK: deferred by a wide task).  (from, seq) orders the hand-overs independently of
 *  the threads and ranks. */
typedef struct {
  uint32_t to, from;
  uint64_t seq;
  int32_t level;  /* the bad element's list, or -1: a pending removal */
  uint32_t t, meta;
  pending_t pv;
  int32_t where;  /* HAND_* */
} handoff_t;

/** A tet recorded with its meta (stale once the tet changes). */
typedef struct {
  uint32_t t, meta;
} tetref_t;

/** A tile: its elements, its slots, its global ids. */
typedef struct {
  badlist_t q[NLEVELS];
  pending_t *pend;
  uint32_t npend, cap_pend;
  badlist_t wq[NLEVELS]; /* octree: elements its task could not do inside the zone: its wide task's */
  pending_t *wpend;
  uint32_t nwpend, cap_wpend;
  i2m_dt_slots_t slots;
  i2m_gidx_t gid_next;
  uint64_t seq;       /* hand-overs made so far */
  double zone[6];     /* lo, hi (world): the tile grown by the margin */
  double wzone[6];    /* octree: the wide task's zone (grown by three margins) */
  i2m_dt_block_t block, wblock; /* octree: the cells its task (its wide task) holds: 3^3 (5^3) */
  uint32_t grant;     /* tets granted per queued element in a phase (doubles when they run out) */
  tetref_t *tets;     /* dist: the tile's tets (whose centroid it holds), stale entries included */
  uint32_t ntets, cap_tets, live_tets; /* (live_tets: when the list was last compacted) */
  bool held;          /* dist: this process holds the tile's tets */
  bool dirty;         /* its lists got elements in an order of no one's (tiles_canonical) */
  uint8_t skip;       /* dist: the sides of the cell its next task goes without (i2m_refine_tile_skip) */
  uint8_t skip_need;  /* dist: sides that elements a task going without some could not do need (all: its next task is whole) */
  i2m_bridge_point_t *pts, *wpts; /* dist: bridge points for its task, its wide task (inserted first) */
  uint32_t npts, cap_pts, nwpts, cap_wpts;
} tile_t;

typedef struct {
  bool octree;                  /* the octree subregions (else the deterministic mode's coarse tiles) */
  int period;                   /* colours: period^3 (2: zones of one colour never meet; 3: blocks) */
  i2m_dt_cells_t cells;         /* the tiles' geometry */
  double side[3], margin[3];
  uint32_t ntiles;
  tile_t *tile;                 /* owned: [ntiles] */
  handoff_t *seq;               /* owned: the sequential pass's elements, in order (coarse tiles) */
  size_t nseq, cap_seq;
  handoff_t *stuck;             /* owned: elements a wide task could not do either (octree) */
  size_t nstuck, cap_stuck;
  handoff_t *merge;             /* owned: scratch of the barrier */
  size_t cap_merge;
  uint32_t *active;             /* owned: [ntiles] the tiles of a phase */
  uint32_t nactive;
  uint64_t *order;              /* owned: [ntiles] scratch: (less work, tile) keys */
  int8_t *level;                /* owned: [slots] reclassification: each tet's list (-1: none) */
  i2m_gidx_t gid_base;          /* ids of this tiling: gid_base + tile << 36 + k */
  int64_t rounds, sequential_ops, wide_tasks;
  int64_t stuck_points;         /* bridge points that not even a wide task could insert */
} tiling_t;

struct i2m_refine_worker {
  char pad_front[64];   /* keeps each worker's busy fields off its neighbours' cache lines */
  i2m_refine_t *r;      /* borrowed */
  i2m_dt_ctx_t ctx;     /* kernel context */
  badlist_t q[NLEVELS]; /* this worker's bad elements */
  pending_t *pend;      /* R7 removals still to do */
  uint32_t npend, cap_pend;
  i2m_gidx_t gid_next, gid_end; /* this worker's block of global ids */
  uint32_t *created;    /* tets created by one operation (copied from ctx->newt) */
  tet_geom_t *geom;     /* [cap_geom] their centres while they are classified */
  uint32_t cap_geom;
  uint32_t ncreated, cap_created;
  i2m_refine_stats_t st;
  i2m_err_t error;      /* the code behind its last I2M_STEP_ERROR (the message is its thread's) */
  i2m_progress_t progress;
  tile_t *tile;         /* deterministic mode: the tile it works on (NULL: none, or the sequential pass) */
  uint32_t tile_id;
  bool tile_full;       /* the tile's slots ran out: stop until the next phase */
  bool tile_wide;       /* it runs the tile's wide task (what it cannot do is stuck) */
  double part_zone[6];  /* dist: the zone of a task that goes without some sides */
  handoff_t *out;       /* this phase's hand-overs */
  size_t nout, cap_out;
  tetref_t *born;       /* dist: the tets it made (filed in their tiles by i2m_refine_dist_merge) */
  uint32_t nborn, cap_born;
  uint32_t *bornv;      /* dist: the vertices it made (filed in the id map) */
  uint32_t nbornv, cap_bornv;
  char pad_back[64];
};

struct i2m_refine {
  const i2m_image_t *img; /* borrowed */
  const i2m_edt_t *edt;   /* borrowed */
  i2m_refine_params_t p;  /* delta resolved; arrays borrowed from the caller */
  double delta;           /* the sampling distance in force: p.delta x scale */
  double delta2;          /* delta^2 */
  double four_delta2;     /* (2 delta)^2 */
  double sin2_facet;      /* sin^2 of the facet angle bound */
  double bisect_tol;      /* bisection tolerance (mm) */
  double min_spacing;
  double size_scale;      /* multiplies delta and every size bound (coarse phase: > 1) */
  double background_shell; /* ... or in the shell of this thickness around it (mm) */
  double background_size2; /* deterministic mode: squared radius above which any tet centred in
                              the labelled block is split (INFINITY: none) */
  double *label_size;     /* owned: [nlabels] size bound per label index (INFINITY: none) */
  i2m_dt_t *dt;           /* owned */
  vgrid_t surf;           /* surface vertices, tagged with their patch (R1) */
  vgrid_t freev;          /* free vertices within 2 delta of an interface (R7) */
  _Atomic int64_t next_gid;
  tiling_t *tiling;       /* owned: the deterministic mode's tiles, or NULL */
  int octree_depth;       /* the octree's depth (2^depth cells along each axis), -1: none set */
  double block_lo[3], block_hi[3]; /* the labelled block (world): where surface points lie */
  int tilings_made;       /* (each tiling has its own range of global ids) */
  i2m_refine_worker_t *workers; /* owned: [nworkers] */
  int nworkers;
  int64_t fragments, fragment_tets; /* fragments relabelled (fragments.c) */
  int64_t bridge_rounds;            /* rounds of the component rule that found a split (bridges.c) */
  i2m_components_t pieces_ic;       /* the image's 6-connected components (pieces.c), once asked for */
  pieces_t pieces;                  /* the pieces of the mesh as it is (pieces_get), when pieces_valid */
  bool pieces_valid;
  bool sliver_pass_ran;             /* a sliver pass changed the mesh (pieces_small_tets) */
  struct sliver_pass *slivers;      /* owned: the sliver perturbation under way (slivers.c), or NULL */
  struct submesh *sub;              /* owned: the dist layer's bookkeeping (submesh.c), or NULL */
  bool async_tasks;                 /* dist, asynchronous mode: a task drops what it hands its
                                       neighbours that has nothing to do (tiles.c, judge_handoffs),
                                       and its slots are granted for a good part of its work
                                       at once (grant_tile) */
};

/* The most tets a fragment may have: PIECE_SMALL_TETS, and PIECE_SLIVER_GROWTH times as many
 * once a sliver pass ran.  The pass refines where slivers are, small pieces of thin
 * structures among them: a speck of 0.56 mm3 that refinement left in 40-60 tets (a fragment)
 * came out of the knee's pass at 6 M tets in 68, and counted as a second piece of its
 * tissue.  The volume bounds, which the pass does not change, still decide. */
static inline int64_t pieces_small_tets(const i2m_refine_t *r)
{
  return r->sliver_pass_ran ? PIECE_SMALL_TETS * PIECE_SLIVER_GROWTH : PIECE_SMALL_TETS;
}

/* refine.c */
/** The mesh's tets renumbered along a space-filling curve (i2m_dt_sort_tets), when nothing else
 *  records tet slots (else nothing is done): the passes after refinement wait less for
 *  memory. */
i2m_err_t refine_sort_tets(i2m_refine_t *r);

/* classify.c */
/** How much tet_geom asks of the image. */
typedef enum {
  PROBE_CENTRE,  /**< the centre and radius only; the label from the payload */
  PROBE_NEW,     /**< at creation: the label at the centre, and the closest interface point */
  PROBE_CLOSEST  /**< the closest interface point within max(r, 2 delta); the label from the payload */
} probe_kind_t;

/** Circumcentre, radius, label and (as asked) what the image says about tet t's centre. */
void tet_geom(const i2m_refine_t *r, uint32_t t, probe_kind_t kind, tet_geom_t *g);
/** tet_geom in two steps: the centre and radius (INFINITY when flat) with the centre's
 *  voxel-frame coordinates, then the rest. */
void tet_centre(const i2m_refine_t *r, uint32_t t, tet_geom_t *g);
void tet_probe(const i2m_refine_t *r, uint32_t t, probe_kind_t kind, tet_geom_t *g);
/** The label a tet with these vertices (in this order) gets at its creation (tet_geom's with
 *  PROBE_NEW), without the rest of the probe. */
int centre_label(const i2m_refine_t *r, const double *const x[4]);
/** centre_label, and whether R3 or R4 fires on that tet (*volume_fires: classify_action would
 *  insert its centre). */
int centre_label_volume(const i2m_refine_t *r, const double *const x[4], bool *volume_fires);
/** Does R5 want a restricted facet with these vertices (all on the interfaces) refined: has
 *  it an angle below the facet bound? */
bool facet_angle_bad(const i2m_refine_t *r, const double *const p[3]);
/** The list a tet (PROBE_NEW or PROBE_CLOSEST) belongs to, or -1.  R1's spacing test looks
 *  at the tet's own vertices only: when none is near, the grid is searched when the tet is
 *  popped (most tets die before their turn). */
int classify_level(i2m_refine_worker_t *w, uint32_t t, const tet_geom_t *g);

/** The action for tet t (its vertices locked), skipping the rules whose bit (1 << rule) is
 *  set in skip (their point could not go in); 0 when nothing is to be done, -1 when R1's
 *  spacing test would look beyond the worker's tile's zone (deterministic mode). */
int classify_action(i2m_refine_worker_t *w, uint32_t t, action_t *a, uint32_t skip);
/** Is it sure, from what the worker's block holds, that no rule wants anything of live tet t
 *  (classify_action would find nothing)?  false when unsure: a face whose other side is not
 *  held, R1 with no surface vertex found near the closest interface point. */
bool classify_nothing_to_do(i2m_refine_worker_t *w, uint32_t t);

/* vgrid.c */
/** A grid of cells of side about h over the box [lo, hi] (grown by one cell). */
i2m_err_t vgrid_init(vgrid_t *g, const double lo[3], const double hi[3], double h);
/** From now on inserts, removals and scans take a per-cell spinlock (several threads use a
 *  grid with removals). */
i2m_err_t vgrid_enable_locks(vgrid_t *g);
void vgrid_free(vgrid_t *g);
/** Room for vertex ids below cap (call while no other thread uses the grid). */
i2m_err_t vgrid_reserve(vgrid_t *g, uint32_t cap);
i2m_err_t vgrid_insert(vgrid_t *g, const i2m_dt_t *dt, uint32_t v, uint32_t tag);
void vgrid_remove(vgrid_t *g, const i2m_dt_t *dt, uint32_t v);
/** Is there a vertex with this tag closer than rad to z? */
bool vgrid_has_within(const vgrid_t *g, const i2m_dt_t *dt, const double z[3], double rad, uint32_t tag);
/** Appends the vertices closer than rad to z, with their global ids, to (*out)[*n ...]. */
i2m_err_t vgrid_collect_within(const vgrid_t *g, const i2m_dt_t *dt, const double z[3], double rad,
                               pending_t **out, uint32_t *n, uint32_t *cap);

/* badlist.c */
i2m_err_t badlist_push(badlist_t *q, const i2m_dt_t *dt, const bad_t *b);
/** Entry i (vertices from the list, or from the mesh for a narrow list). */
void badlist_get(const badlist_t *q, const i2m_dt_t *dt, size_t i, bad_t *b);
/** Takes the top entry (the list must not be empty); false, without reading the tet, when
 *  the tet is gone (its generation moved on). */
bool badlist_pop_live(badlist_t *q, const i2m_dt_t *dt, bad_t *b);
/** Puts b (just popped: its slot is still allocated) at the bottom; the bottom entry moves
 *  to the top.  After a rollback the thread so works elsewhere first, away from the thread
 *  that holds the lock. */
void badlist_requeue_bottom(badlist_t *q, const bad_t *b);
/** Removes the k bottom entries. */
void badlist_drop_bottom(badlist_t *q, size_t k);
/** Makes the list wide or narrow (no other thread may use the mesh meanwhile). */
i2m_err_t badlist_set_wide(badlist_t *q, const i2m_dt_t *dt, bool wide);
void badlist_free(badlist_t *q);

/* tiles.c */
/** Deterministic mode: where an element created now goes.  Returns true when it was handed
 *  over or queued elsewhere (another tile, or the sequential pass), false when it belongs to
 *  the worker's own lists. */
i2m_err_t tiles_route(i2m_refine_worker_t *w, int level, uint32_t t, uint32_t meta, bool *taken);
/** Deterministic mode: the element cannot be done in the tile's zone: the sequential pass
 *  (coarse tiles), the tile's wide task (octree) or nobody (a wide task's) will do it
 *  (level -1: the pending removal pv). */
i2m_err_t tiles_defer(i2m_refine_worker_t *w, int level, uint32_t t, uint32_t meta, pending_t pv);
/** The tile that holds tet t's centroid, and a tile's colour (0..7). */
uint32_t tiles_tile_of_tet(const i2m_refine_t *r, uint32_t t);
uint32_t tiles_tile_of_point(const i2m_refine_t *r, const double x[3]);
int tiles_color(const tiling_t *g, uint32_t id);
/** The first global id of the tiling's range that no tile uses (the one after its last tile's). */
i2m_gidx_t tiles_spare_gid(const tiling_t *g);
/** Worker w takes tile id's lists (its wide lists, wide), slots, zone and block (and gives
 *  them back). */
void tiles_bind(i2m_refine_worker_t *w, uint32_t id, bool wide);
void tiles_unbind(i2m_refine_worker_t *w);
/** The tiles of block b (at most 125: a wide task's), into out; returns their number. */
uint32_t tiles_of_block(const tiling_t *g, const i2m_dt_block_t *b, uint32_t out[125]);
/** A tile arrived (dist): its list of slivers, if a pass keeps one, is not known any more. */
void slivers_forget_tile(i2m_refine_t *r, uint32_t id);
/** A tile's lists in an order of their own: stale entries dropped, elements whose tet the zone
 *  cannot hold moved to the wide lists, each list sorted by tet key, removals by global id.
 *  After bridge points went in: one process inserts them all at once, ranks tile by tile. */
void tiles_canonical(i2m_refine_t *r, uint32_t id);
void tiles_canonical_all(i2m_refine_t *r);

/* ---- regions (regions.c): does a local change keep each tissue's connections? ---- */

/** A port of a region: a boundary face (its sorted vertex slots) whose tet inside and tet
 *  across (slot `across`) carry the same label, with the inside tet's piece; `shared` when
 *  that piece has another port. */
typedef struct {
  uint32_t k[3], piece, across;
  bool shared;
} region_port_t;

/** A region summed up: its ports, the nodes its pieces are numbered among, and the number of
 *  its pieces (of labels other than 0) without a port. */
typedef struct {
  region_port_t *port;
  uint32_t nport, cap_port, nnodes, portless;
} region_t;

/** Scratch space of the region functions (one per thread). */
typedef struct {
  uint32_t *key, *val, *stamp_of, cap, stamp; /* tet slot -> node */
  uint32_t *parent, cap_parent;
  uint32_t *count, cap_count;
  uint16_t *label;
  bool *labelled;
  uint32_t cap_labelled;
  const region_port_t *port_key; /* after's ports, by key (region_keeps) */
  uint32_t *port_at, *port_stamp, cap_pk, pk_stamp;
  uint32_t *failed, nfailed, cap_failed; /* region_keeps: before's pieces whose ports it found apart */
  /* may the tet across face j of tet t (just outside a region) be read?  (NULL: always; a
   * worker's zone: only when nobody else may be changing it) */
  bool (*readable)(const void *arg, uint32_t t, int j);
  const void *readable_arg;
} region_scratch_t;

/** The label of each of the n live tets, or -1 when they differ (or n is 0). */
int region_uniform_label(const i2m_dt_t *dt, const uint32_t *tets, uint32_t n);
/** The region of the n live tets (distinct slots), with their labels now, or each with
 *  label as_label when that is not negative (the region before a change that held tets of
 *  that one label, from the live tets that fill it after the change, or before). */
i2m_err_t region_of_tets(region_scratch_t *S, const i2m_dt_t *dt, const uint32_t *tets, uint32_t n, int as_label,
                         region_t *R);
/** Region R (summed up earlier: its tets are gone, replaced by the `hole` tets that fill it)
 *  grown by the n live tets `extra` around it, into *out. */
i2m_err_t region_grow(region_scratch_t *S, const i2m_dt_t *dt, const region_t *R, const uint32_t *extra, uint32_t n,
                      const uint32_t *hole, uint32_t nhole, region_t *out);
/** Does `after`, whose tets fill the region of `before` anew, join every two tets of a label
 *  just outside it that `before`'s tets of that label joined (through its tets, or through
 *  those tets and their neighbours of that label outside; dt NULL: through its tets only),
 *  with no more portless pieces?  In *keeps.  When only ports are apart, S->failed lists
 *  the pieces of `before` whose ports were (S->nfailed of them). */
i2m_err_t region_keeps(region_scratch_t *S, const i2m_dt_t *dt, const region_t *before, const region_t *after,
                       bool *keeps);
void region_free(region_t *R);
void region_scratch_free(region_scratch_t *S);
/** Dist: bridge point p joins tile id's work (its task inserts it first). */
i2m_err_t tiles_add_point(i2m_refine_t *r, uint32_t id, const i2m_bridge_point_t *p, bool wide);
/** Is world point x in the zone of the worker's tile (always, without a tile)? */
bool tiles_zone_holds(const i2m_refine_worker_t *w, const double x[3]);
/** Does the ball (centre c, squared radius r2) lie in that zone (always, without a tile)? */
bool tiles_ball_fits(const i2m_refine_worker_t *w, const double c[3], double r2);

/* submesh.c */
/** The dist layer's bookkeeping is on: workers record what they make (worker w: its tets and
 *  vertices). */
static inline bool dist_tracking(const i2m_refine_t *r) { return r->sub != NULL; }
i2m_err_t dist_note_tets(i2m_refine_worker_t *w, const uint32_t *t, uint32_t n);
i2m_err_t dist_note_vertex(i2m_refine_worker_t *w, uint32_t v);
/** The label index of the tet across face i of t, another rank's (i2m_refine_dist_ghosts). */
uint16_t dist_ghost_label(const i2m_refine_t *r, uint32_t t, int i);
/** The next face of a local tet whose other side is another rank's, in the table's order
 *  (cursor *h from 0): its 4t + i, sorted global ids and the cell across; false after the
 *  last.  (A walk over those faces only, not over every slot.) */
bool dist_next_remote_face(const i2m_refine_t *r, size_t *h, uint32_t *face, i2m_gidx_t key[3], int32_t *cell);
/** The local face (4t + i) with these sorted global ids whose other side is another rank's,
 *  or I2M_DT_NONE. */
uint32_t dist_face_at(const i2m_refine_t *r, const i2m_gidx_t key[3]);

/* worker.c */
i2m_err_t worker_init(i2m_refine_worker_t *w, i2m_refine_t *r, uint32_t owner, bool locking);
void worker_free(i2m_refine_worker_t *w);
i2m_err_t worker_push(i2m_refine_worker_t *w, uint32_t t);
i2m_err_t worker_push_entry(i2m_refine_worker_t *w, int level, const bad_t *b);
i2m_err_t worker_process_created(i2m_refine_worker_t *w, const uint32_t *newt, uint32_t n);
/** Copies the tets the last operation made (ctx->newt) into w->created. */
i2m_err_t worker_keep_created(i2m_refine_worker_t *w);
/** Treats one pending removal or one bad element: an I2M_STEP_* result. */
int worker_step(i2m_refine_worker_t *w);
/** @p ok, or I2M_STEP_ERROR when @p err is an error: the worker keeps its code (its message is
 *  set) for the caller of the step. */
int step_result(i2m_refine_worker_t *w, i2m_err_t err, int ok);
/** Where a worker ran until its lists were empty: I2M_OK for I2M_STEP_IDLE, the worker's error
 *  for I2M_STEP_ERROR (message kept), an internal error for anything else. */
i2m_err_t step_outcome(const i2m_refine_worker_t *w, int s);

#endif
