/* i2m delaunay layer (layer 3): a 3D Delaunay tetrahedralization in flat arrays.
 *
 * Storage (ARCHITECTURE §2): tet t has vertices tv[4t+i] and, across the face opposite its
 * vertex i, the neighbour tn[4t+i] = 4t'+j (t' the neighbour, j the index of the shared
 * face in t').  Every tet is positively oriented (i2m_orient3d > 0).  A virtual box of 8
 * corners (vertex ids 0..7) encloses everything, so there are no ghost tets and every face
 * has a neighbour except the 12 box-hull faces (tn = I2M_DT_NONE).
 *
 * Per tet, meta[t] packs (generation << 3) | frozen << 2 | mark << 1 | dead.  The generation
 * grows each time the slot is killed, so a (tet, generation) record kept in a work list is
 * recognisably stale once the tet is gone (records keep i2m_dt_stamp: the word without the
 * mark, which a search in another thread may set for a moment).  Dead slots are reused.
 *
 * Degeneracies are decided by symbolic perturbation keyed on each vertex's global id, stored
 * bit-for-bit in the 4th coordinate slot (xyzw[4v+3]) so that coordinates and id share a
 * cache line.
 *
 * Concurrency: all changes go through a per-thread context (i2m_dt_ctx_t).  In a threaded
 * run the context locks every vertex its cavity touches with a compare-and-swap on the
 * vertex lock word and reports I2M_DT_ROLLBACK (having changed nothing) when another thread
 * holds one; in a sequential run locking is off and costs nothing.  Arrays are never
 * reallocated while several contexts are active: capacity is reserved up front
 * (i2m_dt_reserve) and an insertion that would need more returns I2M_DT_FULL. */
#ifndef I2M_DT_H
#define I2M_DT_H

#include <stdatomic.h>
#include <stdbool.h>

#include "i2m/base.h"

#ifdef __cplusplus
extern "C" {
#endif

#define I2M_DT_NONE UINT32_MAX
/** A face whose neighbour lives on another rank (the dist layer): its tet is frozen (a cavity
 *  or a star that reaches it gives I2M_DT_FROZEN, as that side cannot be seen).  Every
 *  neighbour word at or above I2M_DT_REMOTE names no local tet. */
#define I2M_DT_REMOTE (UINT32_MAX - 1)

/** Vertex kinds. */
enum { I2M_VK_DEAD = 0, I2M_VK_BOX = 1, I2M_VK_FREE = 2, I2M_VK_SURFACE = 3 };

/** meta bits. */
#define I2M_TM_DEAD 1u
#define I2M_TM_MARK 2u
#define I2M_TM_FROZEN 4u
#define I2M_TM_GEN_SHIFT 3

typedef struct i2m_dt {
  /* vertices: slots 0..nv-1 (some may be dead) */
  _Atomic uint32_t nv_atomic; /**< vertex slots handed out (high-water mark) */
  uint32_t cap_v;
  double *xyzw;             /**< owned: [cap_v][4] x, y, z, and the global id's bits */
  uint8_t *vkind;           /**< owned: [cap_v] I2M_VK_* */
  uint32_t *vtet;           /**< owned: [cap_v] a live tet incident to the vertex */
  _Atomic uint32_t *vlock;  /**< owned: [cap_v] 0 = free, else owner context id */
  /* tets: slots 0..nt-1 (some dead, on free lists) */
  _Atomic uint32_t nt_atomic; /**< slots handed out (high-water mark) */
  uint32_t cap_t;
  uint32_t *tv;             /**< owned: [cap_t][4] vertex ids */
  uint32_t *tn;             /**< owned: [cap_t][4] 4*t'+j, or I2M_DT_NONE on the box hull */
  _Atomic uint32_t *meta;   /**< owned: [cap_t] generation, frozen, mark, dead */
  unsigned char *tpay;      /**< owned: [cap_t][pay_size] user payload per tet, or NULL */
  size_t pay_size;          /**< bytes of payload per tet (0 = none) */
  /* shared free lists of dead slots (filled by i2m_dt_ctx_flush between parallel phases) */
  uint32_t *free_t;         /**< owned: stack of dead tet slots */
  uint32_t nfree_t, cap_free_t;
  uint32_t *free_v;         /**< owned: stack of dead vertex slots */
  uint32_t nfree_v, cap_free_v;
  double box_lo[3], box_hi[3]; /**< the virtual box corners' extent */
  double shift[3];          /**< the frame: world = coordinates + shift (i2m_dt_set_shift) */
  bool shifted;             /**< shift is not zero: every point inserted is snapped */
} i2m_dt_t;

/** Result of an insertion or removal attempt. */
typedef enum {
  I2M_DT_OK = 0,
  I2M_DT_ROLLBACK,         /**< another thread holds a vertex lock; nothing changed */
  I2M_DT_NOT_IN_CONFLICT,  /**< the seed tet does not contain the point in its circumball */
  I2M_DT_DUPLICATE,        /**< the point coincides with an existing vertex */
  I2M_DT_FROZEN,           /**< the cavity reaches a frozen tet; nothing changed */
  I2M_DT_STALE,            /**< the seed tet is dead or changed since it was recorded */
  I2M_DT_FULL,             /**< not enough reserved capacity; nothing changed */
  I2M_DT_FAILED,           /**< removal could not re-triangulate (never expected) */
  I2M_DT_REFUSED           /**< the context's accept hook refused the cavity; nothing changed */
} i2m_dt_status_t;

/** Boundary face of a cavity: face i of the k-th cavity tet (ki = k << 2 | i) and the
 *  outside neighbour across it (4*u+j, or I2M_DT_NONE on the box hull). */
typedef struct {
  uint32_t ki, out;
} i2m_dt_bface_t;

/** Lock word of a vertex: 0 when free, else owner | local index << I2M_DT_LOCAL_SHIFT.  The
 *  local index numbers the vertices of the cavity being built by the owner. */
#define I2M_DT_OWNER_BITS 10
#define I2M_DT_OWNER_MASK ((1u << I2M_DT_OWNER_BITS) - 1)
#define I2M_DT_MAX_OWNERS I2M_DT_OWNER_MASK

/** Slots a context may hand out without touching shared state: dead slots it collected, and
 *  a range of never-used slots reserved for it.  Owned by the context while it is attached
 *  (a tile of the deterministic mode keeps its own between phases). */
typedef struct {
  uint32_t *pool; uint32_t npool, cap_pool;       /* dead tet slots */
  uint32_t fresh_next, fresh_end;                 /* reserved range of fresh tet slots */
  uint32_t *vpool; uint32_t nvpool, cap_vpool;    /* dead vertex slots */
  uint32_t vfresh_next, vfresh_end;               /* reserved range of fresh vertex slots */
} i2m_dt_slots_t;

/** The cells of a uniform grid over a box (the octree leaves that the dist layer and the
 *  deterministic mode cut the labelled block into): the cell of a point is
 *  floor((x - origin) * inv_side) along each axis, clamped to [0, n - 1] (NaN: 0).  A tet's
 *  cell is its centroid's, summed in its own vertex order: every rank and thread files a tet
 *  in the same cell, and a test on a neighbour of a cavity (i2m_dt_block_t) agrees with it. */
typedef struct {
  double origin[3], inv_side[3];
  int32_t n[3];
} i2m_dt_cells_t;

/** A block of cells, lo[a] <= cell[a] <= hi[a] (a subregion and its buffer zone): every tet an
 *  operation reads as a neighbour of what it changes must lie in it. */
typedef struct {
  i2m_dt_cells_t cells;
  int32_t lo[3], hi[3];
} i2m_dt_block_t;

/** Per-thread context: scratch space, locks held, free-slot pool, statistics. */
typedef struct i2m_dt_ctx {
  i2m_dt_t *dt;            /**< borrowed */
  uint32_t owner;          /**< lock owner tag (>= 1) */
  bool locking;            /**< take vertex locks (threaded runs) */
  uint32_t conflict_owner; /**< after a rollback: the owner of the lock that failed (0: none, or the zone) */
  const double *zone;      /**< borrowed, or NULL: the box [zone[0..2], zone[3..5]] (world) that every
                                vertex an operation touches must lie in, else it rolls back (the
                                deterministic mode: threads work in zones that never meet) */
  bool bounded;            /**< slots only from ctx->slots: when they run out, I2M_DT_FULL (the
                                deterministic mode: a tile's operations never touch shared capacity) */
  const i2m_dt_block_t *block; /**< borrowed, or NULL (only with a zone): the cells the tets next to an
                                operation's cavity or star must lie in, else I2M_DT_FROZEN (a task
                                of the dist layer holds these cells' tets and no others) */
  /* scratch (owned, grown as needed: private to the context) */
  uint32_t *cav; uint32_t ncav, cap_cav;          /* cavity / star tets */
  i2m_dt_bface_t *bnd; uint32_t nbnd, cap_bnd;    /* cavity boundary faces */
  uint32_t *newt; uint32_t nnew, cap_new;         /* tets created by the last operation */
  uint32_t *held; uint32_t nheld, cap_held;       /* vertex locks held = local vertices */
  double *rows;                                   /* [cap_held][4] translated by p, lifted */
  uint32_t *cavl;                                 /* [cap_cav][4] local vertex indices of cav[] */
  uint16_t *etab2;                                /* [128][128] directed edges of local numbers */
  struct i2m_dt_edge *etab; uint32_t ecap, stamp; /* edge table (adjacency of new tets) */
  i2m_dt_slots_t slots;    /**< the slots this context may hand out */
  struct i2m_dt_removal *rm; /**< owned: scratch for vertex removal, created on first use */
  bool journal;            /**< i2m_dt_insert keeps what it replaces, for i2m_dt_undo_insert */
  /** Or NULL: asked by i2m_dt_insert once the cavity of p is known, before anything changes
   *  (the new tets are p joined to the faces i2m_dt_cavity_face lists; the cavity's tets carry
   *  I2M_TM_MARK); false gives I2M_DT_REFUSED.  A caller that would undo most insertions at
   *  once after a look at the new tets looks at them here instead. */
  bool (*accept)(void *arg, const struct i2m_dt_ctx *ctx, const double p[3]);
  void *accept_arg;
  /** Or NULL (zone mode only, with `accept`): asked during the search about each boundary face
   *  k as soon as it is known to be one (the new tet (a, b, c, p) of i2m_dt_cavity_face is then
   *  sure to be made if the insertion goes on); false stops the search with I2M_DT_REFUSED.
   *  ctx->nbnd_seen tells `accept` how many faces it has seen. */
  bool (*accept_face)(void *arg, const struct i2m_dt_ctx *ctx, uint32_t k, const double p[3]);
  uint32_t nbnd_seen;
  struct i2m_dt_journal *jr; /**< owned: that record, created on first use */
  /* statistics */
  int64_t n_insert, n_remove, n_rollback, n_created, n_killed, n_walk_steps;
} i2m_dt_ctx_t;

/** Creates a triangulation of the virtual box [lo, hi] (8 corners, ids 0..7) with room for
 *  about @p nv_hint vertices.  @p pay_size bytes of payload per tet (0 for none). */
i2m_err_t i2m_dt_create(const double lo[3], const double hi[3], uint32_t nv_hint, size_t pay_size,
                        i2m_dt_t **out);
void i2m_dt_destroy(i2m_dt_t **dt);

/** Makes room for at least nv vertices and nt tets (all contexts must be idle). */
i2m_err_t i2m_dt_reserve(i2m_dt_t *dt, uint32_t nv, uint32_t nt);

/** A dead tet slot (from the shared free list, else a fresh one; grows the arrays), alive
 *  (generation moved on) with unset vertices and neighbours.  All contexts idle. */
i2m_err_t i2m_dt_take_tet(i2m_dt_t *dt, uint32_t *t);
/** A dead vertex slot (as i2m_dt_take_tet), of kind I2M_VK_DEAD until the caller sets it. */
i2m_err_t i2m_dt_take_vertex(i2m_dt_t *dt, uint32_t *v);
/** Kills tet t (generation moved on) and files its slot in the free list.  All contexts idle. */
i2m_err_t i2m_dt_give_tet(i2m_dt_t *dt, uint32_t t);
/** Kills vertex v and files its slot in the free list.  All contexts idle. */
i2m_err_t i2m_dt_give_vertex(i2m_dt_t *dt, uint32_t v);

/** Sets the frame's shift s (world = coordinates + s; before any insertion).  From then on
 *  every point inserted or located is first snapped to q = fl(fl(p + s) - s), so that q + s is
 *  a double: adding s back is exact and the world mesh is this one translated, with the same
 *  orientations.  The snap moves a point by at most half an ulp of the world coordinate; a
 *  point on its seed's sphere may then fall outside it (I2M_DT_NOT_IN_CONFLICT, as for any
 *  point on the sphere).  Each |s[a]| must be at least twice every |coordinate| (Sterbenz:
 *  the subtraction is then exact). */
void i2m_dt_set_shift(i2m_dt_t *dt, const double s[3]);

/** The point the triangulation takes for p: p itself, or its snap into q (see above). */
static inline const double *i2m_dt_snap(const i2m_dt_t *dt, const double p[3], double q[3])
{
  if (!dt->shifted) return p;
  for (int a = 0; a < 3; a++) {
    const double w = p[a] + dt->shift[a]; /* (rounded: the world coordinate) */
    q[a] = w - dt->shift[a];              /* (exact) */
  }
  return q;
}

/** Initialises a context for @p dt; owner >= 1 distinguishes threads. */
i2m_err_t i2m_dt_ctx_init(i2m_dt_ctx_t *ctx, i2m_dt_t *dt, uint32_t owner, bool locking);
void i2m_dt_ctx_free(i2m_dt_ctx_t *ctx);
/** Returns the context's pooled dead slots to the shared free list (contexts idle). */
void i2m_dt_ctx_flush(i2m_dt_ctx_t *ctx);

/** Inserts point @p p (global id @p gid, kind @p kind) whose cavity contains tet @p seed.
 *  @p seed_meta is meta[seed] when the seed was recorded (checked after locking; pass
 *  I2M_DT_NONE to skip the check).  On I2M_DT_OK, *vout is the new vertex and ctx->newt
 *  lists the new tets; the locks are still held until i2m_dt_unlock_all (so the caller can
 *  classify the new tets safely).  On any other status nothing changed and no lock is held. */
i2m_dt_status_t i2m_dt_insert(i2m_dt_ctx_t *ctx, const double p[3], i2m_gidx_t gid, uint8_t kind,
                              uint32_t seed, uint32_t seed_meta, uint32_t *vout);

/** The vertices a, b, c of the k-th tet an insertion would make of its cavity (k < ctx->nbnd,
 *  inside the accept hook): the tet is (a, b, c, p), in this order. */
void i2m_dt_cavity_face(const i2m_dt_ctx_t *ctx, uint32_t k, uint32_t abc[3]);

/** Undoes the last insertion of a context whose `journal` was set (sequential use, or a zone's;
 *  no other operation of the context in between): its vertex and tets go, and the tets its
 *  cavity held come back in their slots, with their generations and payloads, so that every
 *  reference to them holds again, and the slots the insertion took go back to the context
 *  (where they came from, when it can tell).  Far cheaper than removing the vertex, which
 *  gives the same triangulation in other slots. */
i2m_err_t i2m_dt_undo_insert(i2m_dt_ctx_t *ctx);

/** Finds a tet containing p by a visibility walk from @p start (sequential use, or a zone's
 *  with a block: I2M_DT_NONE when the walk would leave the block; faces of another rank's
 *  are closed). */
uint32_t i2m_dt_locate(i2m_dt_ctx_t *ctx, const double p[3], uint32_t start);

/** Inserts p after locating it from @p start (sequential use).  Duplicate points return
 *  I2M_DT_DUPLICATE and change nothing; a walk that would leave the context's block,
 *  I2M_DT_FROZEN. */
i2m_dt_status_t i2m_dt_insert_walk(i2m_dt_ctx_t *ctx, const double p[3], i2m_gidx_t gid,
                                   uint8_t kind, uint32_t start, uint32_t *vout);

/** Moves vertex @p v (not a box corner) to p, keeping its tets, when they stay positive and
 *  locally Delaunay across every face with v there (then they are the Delaunay
 *  tetrahedralization of the moved points, the one a removal and a reinsertion would give):
 *  I2M_DT_OK, ctx->newt lists v's tets (the same slots and generations) and the locks are held
 *  (as for insert).  I2M_DT_NOT_IN_CONFLICT when some would not be Delaunay, or the statuses of
 *  i2m_dt_remove (its star reaches a frozen or another rank's tet, ...): nothing changed. */
i2m_dt_status_t i2m_dt_move(i2m_dt_ctx_t *ctx, uint32_t v, const double p[3]);

/** Removes vertex @p v (not a box corner): its star is re-triangulated with the same
 *  symbolic perturbation, so the result is the Delaunay tetrahedralization without v.
 *  On I2M_DT_OK ctx->newt lists the new tets and the locks are held (as for insert). */
i2m_dt_status_t i2m_dt_remove(i2m_dt_ctx_t *ctx, uint32_t v);

/** Renumbers the live tets 0 .. n-1 cell by cell, the cells of a grid over the box [lo, hi]
 *  (the triangulation's frame) taken in Morton order, the dead slots dropped (the free list
 *  emptied): a tet's neighbours then mostly lie in nearby slots, and the searches that follow
 *  wait far less for memory.  Each tet keeps its vertices, adjacency, payload and generation,
 *  in its new slot.  All contexts idle with every slot set returned; any tet slot recorded
 *  elsewhere names another tet afterwards. */
i2m_err_t i2m_dt_sort_tets(i2m_dt_t *dt, const double lo[3], const double hi[3]);

/** Reserves slots for a context's (or a tile's) slot set: dead slots from the shared free
 *  lists first, then a fresh range, so that @p s holds at least ntets and nverts.  Grows the
 *  arrays when needed.  Not while any context works on the triangulation. */
i2m_err_t i2m_dt_slots_grant(i2m_dt_t *dt, i2m_dt_slots_t *s, uint32_t ntets, uint32_t nverts);
/** Returns a slot set's slots to the shared free lists (it keeps its pools' memory). */
void i2m_dt_slots_return(i2m_dt_t *dt, i2m_dt_slots_t *s);
/** The same, and frees its pools. */
void i2m_dt_slots_release(i2m_dt_t *dt, i2m_dt_slots_t *s);

/** Releases every vertex lock held by the context. */
void i2m_dt_unlock_all(i2m_dt_ctx_t *ctx);

/** Takes the locks of the four vertices v4 (threaded runs; no-op otherwise).  False when
 *  another context holds one: the locks taken so far stay held (release with
 *  i2m_dt_unlock_all); ctx->conflict_owner names the holder. */
bool i2m_dt_lock_tet(i2m_dt_ctx_t *ctx, const uint32_t v4[4]);

/** Bulk insertion of n points (xyz[3n]); point k gets global id gid0 + k.  Points are
 *  inserted in BRIO order along a Hilbert curve (seeded by @p seed).  Duplicates are
 *  skipped and counted in *nduplicates (may be NULL).  vid_out (may be NULL) receives each
 *  point's vertex id (I2M_DT_NONE for a skipped duplicate). */
i2m_err_t i2m_dt_insert_points(i2m_dt_t *dt, const double *xyz, int64_t n, i2m_gidx_t gid0,
                               uint64_t seed, uint32_t *vid_out, int64_t *nduplicates);

/** Validity check: positive orientation, symmetric adjacency with matching faces, empty
 *  circumspheres (local Delaunay under the perturbation), vertex hints.  Returns I2M_OK or
 *  I2M_ERR_INTERNAL with a message describing the first violation. */
i2m_err_t i2m_dt_check(const i2m_dt_t *dt, bool check_delaunay);

/** Order-independent checksum of the tetrahedralization (sum of hashes of each live tet's
 *  sorted global ids), and the number of live tets. */
uint64_t i2m_dt_checksum(const i2m_dt_t *dt, int64_t *ntets);

/** Number of live tets (scans meta). */
int64_t i2m_dt_count_tets(const i2m_dt_t *dt);

/* ---- small inline accessors ---- */
static inline i2m_gidx_t i2m_dt_gid(const i2m_dt_t *dt, uint32_t v)
{
  union { double d; int64_t i; } u;
  u.d = dt->xyzw[4 * (size_t)v + 3];
  return u.i;
}
static inline const double *i2m_dt_xyz(const i2m_dt_t *dt, uint32_t v) { return dt->xyzw + 4 * (size_t)v; }
static inline uint32_t i2m_dt_meta(const i2m_dt_t *dt, uint32_t t)
{
  return atomic_load_explicit(&dt->meta[t], memory_order_relaxed);
}
/** meta[t] without the mark: what a record of the tet keeps and later compares.  Another
 *  thread's cavity search marks the live tets it visits for a moment (and unmarks them if it
 *  rolls back): a record compared with the marked word would take a live tet for gone. */
static inline uint32_t i2m_dt_stamp(const i2m_dt_t *dt, uint32_t t) { return i2m_dt_meta(dt, t) & ~I2M_TM_MARK; }
static inline bool i2m_dt_alive(const i2m_dt_t *dt, uint32_t t) { return !(i2m_dt_meta(dt, t) & I2M_TM_DEAD); }
static inline uint32_t i2m_dt_nverts_slots(const i2m_dt_t *dt)
{
  return atomic_load_explicit(&dt->nv_atomic, memory_order_relaxed);
}
static inline uint32_t i2m_dt_ntets_slots(const i2m_dt_t *dt)
{
  return atomic_load_explicit(&dt->nt_atomic, memory_order_relaxed);
}
/** Number of live tets when no context holds slots of its own (every free slot is on the
 *  shared free list): no scan. */
static inline int64_t i2m_dt_live_tets_quiescent(const i2m_dt_t *dt)
{
  return (int64_t)i2m_dt_ntets_slots(dt) - (int64_t)dt->nfree_t;
}
static inline void *i2m_dt_payload(const i2m_dt_t *dt, uint32_t t) { return dt->tpay + dt->pay_size * t; }

/** Tet t's centroid, summed in its vertex order. */
static inline void i2m_dt_centroid(const i2m_dt_t *dt, uint32_t t, double c[3])
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  c[0] = c[1] = c[2] = 0.0;
  for (int i = 0; i < 4; i++)
    for (int a = 0; a < 3; a++) c[a] += i2m_dt_xyz(dt, v[i])[a];
  for (int a = 0; a < 3; a++) c[a] *= 0.25;
}

/** The cell of coordinate x along axis a (clamped; NaN: 0). */
static inline int32_t i2m_dt_cell_axis(const i2m_dt_cells_t *g, int a, double x)
{
  const double u = (x - g->origin[a]) * g->inv_side[a];
  return !(u >= 0.0) ? 0 : u >= (double)g->n[a] ? g->n[a] - 1 : (int32_t)u;
}

/** The cell of tet t (its centroid's). */
static inline void i2m_dt_tet_cell(const i2m_dt_t *dt, uint32_t t, const i2m_dt_cells_t *g, int32_t cell[3])
{
  double c[3];
  i2m_dt_centroid(dt, t, c);
  for (int a = 0; a < 3; a++) cell[a] = i2m_dt_cell_axis(g, a, c[a]);
}

/** Does the block hold tet t? */
static inline bool i2m_dt_block_holds(const i2m_dt_t *dt, const i2m_dt_block_t *b, uint32_t t)
{
  int32_t c[3];
  i2m_dt_tet_cell(dt, t, &b->cells, c);
  return c[0] >= b->lo[0] && c[0] <= b->hi[0] && c[1] >= b->lo[1] && c[1] <= b->hi[1] && c[2] >= b->lo[2] &&
         c[2] <= b->hi[2];
}

#ifdef __cplusplus
}
#endif
#endif
