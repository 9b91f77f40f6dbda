/* Refine layer: sliver perturbation, an optional pass after refinement (REFERENCE §3.9).
 *
 * Delaunay refinement bounds the radius-edge ratio, which leaves slivers: four nearly
 * coplanar vertices on a small circumsphere.  For every output tet whose smallest dihedral
 * angle is below the bound, worst first, a new vertex goes in at its circumcentre (on the
 * closest interface point when that is within delta), kept when the new tets pass every rule
 * and beat the sliver; else each of its vertices is moved in turn to a few
 * random nearby points: the vertex is removed and reinserted there (same global id, so the
 * same perturbation), the changed tets are labelled and judged by the very rules refinement
 * ended with, and the move is kept only when every changed tet passes them and the smallest
 * dihedral angle among the changed tets exceeds the worst of the vertex's old star.
 * Otherwise the vertex goes back where it was, which restores the same triangulation (a
 * Delaunay triangulation is unique under the perturbation).  A surface vertex moves to the
 * closest point of its own interface patch to a random nearby point, so it stays on the
 * interface: the worst slivers are flat tets of four surface vertices on a planar stretch of
 * voxel faces (four nearly cocircular points), which only such a move can lift.  Every rule
 * holds after every kept move, so every guarantee of refinement holds at the end; and no
 * change may cut a tissue's path of tets through the region it changes (regions.c), unless a
 * way round is found nearby, so every tissue the component rule made one piece stays one.  A last
 * stage treats the tets with too wide an angle too (tet_badness), keeping only changes whose
 * output tets are within both bounds.
 *
 * The work runs on the deterministic mode's tiles (tiles.c): in each round, the slivers of
 * the tiles of one colour at a time, each tile by one thread inside its zone, then a
 * sequential pass for the slivers whose move could not stay in a zone.  A tile's slivers are
 * treated in the order of their angle and their vertices' global ids, with random moves
 * drawn from a generator seeded by the round and the tile: the result depends on the mesh
 * only, not on the number of threads or on slot numbers. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

#define MOVES_PER_VERTEX 8 /* random targets tried per vertex of a sliver */
#define PICKS 4            /* points of a sliver's picking region tried after its circumcentre */
#define PICK_RADIUS 0.5    /* the picking region: this times the circumradius around the centre */
#define WIDE_PICKS 32      /* in a wide round: more points, from a larger region */
#define WIDE_PICK_RADIUS 0.8
#define NEAR 0.2           /* at a distance from NEAR to REACH times the vertex's shortest edge */
#define REACH 0.5
#define WIDE_MOVES 32      /* in a wide round (after a round that kept no move): more, and farther */
#define WIDE_REACH 0.7
#define ROUNDS 40          /* rounds over the slivers left (later ones are short) */
#define WALK_STEPS 64      /* a target farther than this from the vertex's old star: deferred */
#define FIRST_STAGE 5.0    /* degrees: a higher bound is reached after the slivers below this */
#define WATCH_MARGIN 5.0   /* degrees: the tets watched have an angle below the bound plus this */
#define TASK_ROUNDS 4      /* dist: rounds of a task over its tile's slivers (see tile_slivers_dist) */
#define WAY_ROUND 512      /* tets a search for a way round a change's cut may visit */

/* A sliver, with its vertices' global ids in increasing order (the order of the work). */
typedef struct {
  uint32_t t, meta;
  double angle;
  i2m_gidx_t gid[4];
} sliver_t;

typedef struct {
  sliver_t *a;
  size_t n, cap;
} sliver_list_t;

/* A watched tet (one process): an output tet with an angle below the bound plus WATCH_MARGIN
 * or too wide, as it was when last changed (in round `round`, 0: before the pass), with its
 * largest and smallest dihedral cosines. */
typedef struct {
  uint32_t t, meta, round;
  double hi, lo;
} watched_t;

typedef struct {
  watched_t *a;
  size_t n, cap;
} watch_list_t;

/* A tet a change made, with its largest and smallest dihedral cosines then. */
typedef struct {
  uint32_t t, meta;
  double hi, lo;
} touched_t;

/* One thread's working set. */
typedef struct {
  i2m_refine_worker_t *w; /* its worker: kernel context and rule evaluation */
  uint32_t *star, nstar, cap_star;
  uint32_t *seen, *seen_stamp, cap_seen, stamp; /* star_of's set of the tets found (open addressing) */
  uint32_t *changed, nchanged, cap_changed;
  double *hole_cos;                         /* [cap_hole] a removal's tets' largest dihedral cosines */
  uint32_t *hole_meta, cap_hole;            /* [cap_hole] and generations */
  touched_t *touched;                       /* the tets this round's changes made that may be */
  uint32_t ntouched, cap_touched;           /* slivers or worth watching (note_touched) */
  uint32_t *reshaped, nreshaped, cap_reshaped; /* the tets of this round's moves in place */
  sliver_list_t deferred;                   /* slivers a zone could not hold */
  sliver_list_t inner;                      /* dist: a task's later rounds' slivers */
  uint32_t *stale, nstale, cap_stale;       /* dist: tiles beyond its tasks' blocks that got tets */
  uint32_t *saved, cap_saved;               /* an in-place move's tets: labels and tiles before */
  uint64_t rng;
  int64_t tried, kept, in_place, in_place_kept; /* in_place: the moves tried without a removal */
  int64_t inserted;                         /* the points added (kept insertions) */
  double trial_floor;                       /* the trial under way: its floor (trial_accept), */
  uint8_t trial_kind;                       /* its point's kind, */
  uint16_t *new_label;                      /* [cap_new_label] and the labels of the tets it makes */
  uint32_t cap_new_label;
  int64_t prejudged;                        /* trials refused before their insertion by a rule */
  int64_t dropped;                          /* vertices left out (try_drop) */
  /* the change under way's region before and after it (regions.c): a vertex's star as it was
   * before its removal, and the tets a trial's cavity took beyond the hole */
  region_t star_before, was, now;
  const region_t *before;                   /* star_before or was */
  int before_label, star_label;             /* >= 0: the region held tets of this label only
                                               (summed up when needed, from the tets after) */
  uint32_t *queue, cap_queue;               /* the search for a way round a cut */
  uint32_t *extra, nextra, cap_extra;       /* a trial's cavity tets beyond the hole; after a
                                               change, its live tets (alive_changed) */
  region_scratch_t regions;
  int64_t cut;                              /* changes refused as they would cut a tissue's path */
} perturb_t;

struct sliver_pass {
  double bound, final_bound, t0; /* the stage's bound, the one asked for */
  int round, stage_start;        /* rounds so far (they seed the moves); the stage's first */
  i2m_gidx_t seq_gid;            /* the next global id of a point the sequential part inserts */
  bool caps;                     /* the last stage: the tets with too wide an angle too */
  double cap_shift;              /* tet_badness's mirror for the wide angles (final bound's) */
  double cos_final;              /* cos(final_bound) */
  int64_t kept_before_round;
  bool wide;                     /* this round tries WIDE_MOVES targets up to WIDE_REACH */
  perturb_t *per;        /* [nworkers] */
  sliver_list_t list;    /* the round's slivers, in order */
  uint64_t *seen_bits;   /* a bit per tet slot, all clear between rounds (collect_after_round) */
  size_t nseen_bits;
  uint32_t *first;       /* [ntiles + 1]: tile id's slivers are by_tile[first[id] .. first[id + 1]) */
  sliver_t *by_tile;     /* [list.n] */
  uint32_t *active, nactive;
  i2m_sliver_stats_t st;
  i2m_progress_t progress;
  /* One process keeps the tets worth a look up to date (watch_*): a stage's list and the
   * closing figures come from them, not from a pass over the mesh (the angles of every tet:
   * a quarter of the pass's time when it made four) */
  bool watching;
  double cos_watch;       /* cos(final_bound + WATCH_MARGIN) */
  watch_list_t watch;     /* every output tet worth a look has a valid entry (watch_valid) */
  uint8_t *changed_in;    /* [nchanged_in] per tet slot: the round of its last move in place, 0 none */
  size_t nchanged_in;
  /* Under the dist layer: each held tile's slivers, in order (its task's list; their number is
   * the tile's work for the scheduler), made by a look at the tile's tets and then kept up to
   * date by the tasks that change the tile (the entries still alive, and the slivers among
   * the tets the task made), until the tile arrives from another rank or the stage changes
   * what counts.  The rounds' seeds looked at every held tile's tets anew, and the tasks
   * again: on the knee at 2 ranks, 15 degrees, a tenth of each rank's time in the pass. */
  sliver_list_t *cache;   /* [ncache] */
  uint8_t *cache_ok;      /* [ncache] */
  uint32_t ncache;
  double cache_bound;     /* the stage the lists are of */
  bool cache_caps;
};

enum { MOVE_ERROR = -1, MOVE_UNDONE = 0, MOVE_KEPT = 1, MOVE_DEFERRED = 2, MOVE_NOT_IN_PLACE = 3 };

static void sort4_gid(i2m_gidx_t g[4], uint32_t v[4])
{
  for (int i = 1; i < 4; i++)
    for (int j = i; j > 0 && g[j] < g[j - 1]; j--) {
      const i2m_gidx_t x = g[j];
      const uint32_t y = v[j];
      g[j] = g[j - 1], g[j - 1] = x;
      v[j] = v[j - 1], v[j - 1] = y;
    }
}

static double uniform01(uint64_t *s) { return (double)(i2m_xorshift64(s) >> 11) * 0x1.0p-53; }

/* A random point of the unit ball at a squared norm of min_n2 at least (rejection from the
 * cube); returns its squared norm. */
static double random_in_ball(uint64_t *s, double d[3], double min_n2)
{
  double n2;
  do {
    for (int a = 0; a < 3; a++) d[a] = 2.0 * uniform01(s) - 1.0;
    n2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  } while (n2 > 1.0 || n2 < min_n2);
  return n2;
}

/* The generator of one (round, tile) pair (TILE_NONE: the sequential pass). */
static uint64_t rng_seed(const i2m_refine_t *r, int round, uint32_t tile)
{
  uint64_t s = (r->p.seed ^ 0x9E3779B97F4A7C15ull) + (uint64_t)round * 0xBF58476D1CE4E5B9ull + (uint64_t)tile * 0x94D049BB133111EBull;
  s ^= s >> 31;
  return s ? s : 1;
}

/* How bad a tet is, as a cosine (the pass's one measure: lists, floors, trials): the largest of
 * its dihedral cosines (its smallest angle); in the last stage (caps), the larger of that and
 * its smallest cosine c (its largest angle) mirrored as cap_shift - c, where cap_shift =
 * cos(A) + cos(W) for the bound A and the widest angle allowed W = 180 - 4/3 A (160 degrees at
 * A = 15): a tet with an angle of W counts as one with an angle of A, a wider one as worse.
 * *cmax (if not NULL) gets the largest cosine alone. */
static double badness_from(const struct sliver_pass *S, double hi, double lo)
{
  const double wide = S->cap_shift - lo;
  return S->caps && wide > hi ? wide : hi;
}

/* The largest and smallest of a tet's dihedral cosines cs. */
static void extremes_of(const double cs[6], double *hi, double *lo)
{
  *hi = -1.0;
  *lo = 1.0;
  for (int e = 0; e < 6; e++) {
    *hi = cs[e] > *hi ? cs[e] : *hi;
    *lo = cs[e] < *lo ? cs[e] : *lo;
  }
}

/* Is the tet with vertices x at least as bad as f (badness_from's measure): its smallest
 * angle's cosine at least f, or, in the caps' stage, its largest's at most cap_shift - f?
 * Without a root or a division (a trial looks at every tet it would make: most of the pass's
 * angles). */
static bool as_bad_as(const struct sliver_pass *S, const double *const x[4], double f)
{
  double num[6], den2[6];
  i2m_tet_dihedral_terms(x[0], x[1], x[2], x[3], num, den2);
  bool bad = false;
  for (int e = 0; e < 6; e++) bad |= i2m_cosine_at_least(num[e], den2[e], f);
  for (int e = 0; e < 6 && S->caps; e++) bad |= i2m_cosine_at_least(-num[e], den2[e], f - S->cap_shift);
  return bad;
}

static void tet_cosines(const i2m_refine_t *r, uint32_t t, double cs[6])
{
  const double *x[4];
  tet_points(r->dt, t, x);
  i2m_tet_dihedral_cosines(x[0], x[1], x[2], x[3], cs);
}

static void tet_extremes(const i2m_refine_t *r, uint32_t t, double *hi, double *lo)
{
  double cs[6];
  tet_cosines(r, t, cs);
  extremes_of(cs, hi, lo);
}

static double tet_badness(const i2m_refine_t *r, uint32_t t, double *cmax)
{
  double hi, lo;
  tet_extremes(r, t, &hi, &lo);
  if (cmax) *cmax = hi;
  return badness_from(r->slivers, hi, lo);
}

static double widest_allowed(double bound) { return 180.0 - bound * 4.0 / 3.0; }

/* The floor a change's output tets must beat: in the caps' stage, every one of them must also
 * be within both bounds (a wide angle is not traded for a small one: the stages before left
 * no tet below the bound, and this one must not make any). */
static double floor_of(const i2m_refine_t *r, double worst)
{
  const struct sliver_pass *S = r->slivers;
  return S->caps && worst > S->cos_final ? S->cos_final : worst;
}

static i2m_err_t grow_list(uint32_t **a, uint32_t *cap, uint32_t need)
{
  if (need <= *cap) return I2M_OK;
  uint32_t c = need + need / 2 + 32;
  I2M_CALL(i2m_realloc(c, sizeof **a, a));
  *cap = c;
  return I2M_OK;
}

static i2m_err_t list_push(sliver_list_t *L, const sliver_t *s)
{
  if (L->n == L->cap) {
    L->cap = L->cap ? 2 * L->cap : 1024;
    I2M_CALL(i2m_realloc(L->cap, sizeof *L->a, &L->a));
  }
  L->a[L->n++] = *s;
  return I2M_OK;
}

static int cmp_sliver(const void *x, const void *y)
{
  const sliver_t *a = x, *b = y;
  if (a->angle != b->angle) return (a->angle > b->angle) - (a->angle < b->angle);
  for (int i = 0; i < 4; i++)
    if (a->gid[i] != b->gid[i]) return (a->gid[i] > b->gid[i]) - (a->gid[i] < b->gid[i]);
  return 0;
}

/* ---- one move ---- */

/* Files tet t in star_of's set; false when it was there. */
static bool seen_add(perturb_t *P, uint32_t t)
{
  const uint32_t mask = P->cap_seen - 1;
  for (uint32_t h = (t * 0x9E3779B1u) >> 7 & mask;; h = (h + 1) & mask) {
    if (P->seen_stamp[h] != P->stamp) {
      P->seen_stamp[h] = P->stamp;
      P->seen[h] = t;
      return true;
    }
    if (P->seen[h] == t) return false;
  }
}

/* An empty set with room for n tets at half load. */
static i2m_err_t seen_clear(perturb_t *P, uint32_t n)
{
  if (2 * n > P->cap_seen) {
    uint32_t c = P->cap_seen ? P->cap_seen : 256;
    while (c < 2 * n) c *= 2;
    I2M_CALL(i2m_realloc(c, sizeof *P->seen, &P->seen));
    I2M_CALL(i2m_realloc(c, sizeof *P->seen_stamp, &P->seen_stamp));
    memset(P->seen_stamp, 0, c * sizeof *P->seen_stamp);
    P->cap_seen = c;
    P->stamp = 0;
  }
  if (++P->stamp == 0) { /* (wrapped: every entry would look current) */
    memset(P->seen_stamp, 0, P->cap_seen * sizeof *P->seen_stamp);
    P->stamp = 1;
  }
  return I2M_OK;
}

/* The tets incident to vertex v (breadth-first across the faces that hold v). */
static i2m_err_t star_of(perturb_t *P, uint32_t v)
{
  const i2m_dt_t *dt = P->w->r->dt;
  P->nstar = 0;
  I2M_CALL(grow_list(&P->star, &P->cap_star, 1));
  I2M_CALL(seen_clear(P, 64));
  P->star[P->nstar++] = dt->vtet[v];
  seen_add(P, dt->vtet[v]);
  for (uint32_t k = 0; k < P->nstar; k++) {
    const uint32_t t = P->star[k], *tv = dt->tv + 4 * (size_t)t;
    for (uint32_t i = 0; i < 4; i++) {
      if (tv[i] == v) continue; /* the face opposite v does not hold it */
      const uint32_t n = dt->tn[4 * (size_t)t + i];
      if (n >= I2M_DT_REMOTE) continue; /* (never for a face that holds v: see take_out) */
      const uint32_t u = n >> 2;
      if (2 * (P->nstar + 1) > P->cap_seen) { /* (a large star: the set grows, refilled) */
        I2M_CALL(seen_clear(P, P->nstar + 1));
        for (uint32_t q = 0; q < P->nstar; q++) seen_add(P, P->star[q]);
      }
      if (!seen_add(P, u)) continue;
      I2M_CALL(grow_list(&P->star, &P->cap_star, P->nstar + 1));
      P->star[P->nstar++] = u;
    }
  }
  return I2M_OK;
}

/* Tet t's label from its circumcentre, as at its creation. */
static void label_tet(const i2m_refine_t *r, uint32_t t)
{
  const double *x[4];
  tet_points(r->dt, t, x);
  tinfo(r->dt, t)->label = (uint16_t)centre_label(r, x);
}

/* Where the grids place a vertex: the surface vertices' (with its patch) and R7's. */
typedef struct {
  bool surface, near;
  uint32_t tag;
} vplace_t;

static vplace_t place_of(const i2m_refine_t *r, uint32_t v)
{
  vplace_t g = {r->dt->vkind[v] == I2M_VK_SURFACE, v < r->freev.cap_next && r->freev.tag[v] == VGRID_MEMBER, 0};
  if (g.surface) g.tag = r->surf.tag[v];
  return g;
}

/* Vertex v out of its grids, or into them at its place now. */
static void grids_out(i2m_refine_t *r, uint32_t v, vplace_t g)
{
  if (g.surface) vgrid_remove(&r->surf, r->dt, v);
  if (g.near) vgrid_remove(&r->freev, r->dt, v);
}

static i2m_err_t grids_in(i2m_refine_t *r, uint32_t v, vplace_t g)
{
  if (g.surface) I2M_CALL(vgrid_insert(&r->surf, r->dt, v, g.tag));
  if (g.near) I2M_CALL(vgrid_insert(&r->freev, r->dt, v, VGRID_MEMBER));
  return I2M_OK;
}

/* Appends the tets the last kernel operation created to the changed list, labelled (the
 * rules compare neighbours' labels) unless the caller labels them later (changed_ok). */
static i2m_err_t note_created(perturb_t *P, bool label)
{
  i2m_refine_t *r = P->w->r;
  const i2m_dt_ctx_t *ctx = &P->w->ctx;
  I2M_CALL(grow_list(&P->changed, &P->cap_changed, P->nchanged + ctx->nnew));
  for (uint32_t k = 0; k < ctx->nnew; k++) {
    if (label) label_tet(r, ctx->newt[k]);
    P->changed[P->nchanged++] = ctx->newt[k];
  }
  return dist_tracking(r) ? dist_note_tets(P->w, ctx->newt, ctx->nnew) : I2M_OK;
}

/* Takes vertex v out of the mesh (and out of its grid: the surface vertices', or R7's); its
 * hole's tets join the changed list, labelled (the trials into the hole read their labels). */
static i2m_dt_status_t take_out(perturb_t *P, uint32_t v)
{
  i2m_refine_t *r = P->w->r;
  i2m_dt_ctx_t *ctx = &P->w->ctx;
  const vplace_t g = place_of(r, v);
  grids_out(r, v, g);
  const i2m_dt_status_t st = i2m_dt_remove(ctx, v);
  i2m_dt_unlock_all(ctx);
  if (st != I2M_DT_OK) return grids_in(r, v, g) == I2M_OK ? st : I2M_DT_FAILED;
  return note_created(P, true) == I2M_OK ? I2M_DT_OK : I2M_DT_FAILED;
}

/* Does the worker's zone (if any) hold every vertex of the face of tet t opposite i?  Only
 * then is the tet across it sure to change for nobody else meanwhile. */
static bool face_in_zone(const i2m_refine_worker_t *w, const i2m_dt_t *dt, uint32_t t, int i)
{
  if (!w->tile) return true;
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (int j = 0; j < 4; j++)
    if (j != i && tiles_zone_holds(w, i2m_dt_xyz(dt, v[j]))) return true;
  return false;
}

/* A tet that holds p, by a visibility walk from tet t that never crosses into a tet no vertex
 * of whose face lies in the zone (those may be changing); I2M_DT_NONE when it would. */
static uint32_t locate_near(const i2m_refine_worker_t *w, uint32_t t, const double p[3])
{
  const i2m_dt_t *dt = w->r->dt;
  for (int step = 0; step < WALK_STEPS; step++) {
    const uint32_t *v = dt->tv + 4 * (size_t)t;
    int beyond = -1;
    for (int i = 0; i < 4 && beyond < 0; i++) {
      const double *q[4] = {i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]), i2m_dt_xyz(dt, v[3])};
      q[i] = p;
      if (i2m_orient3d(q[0], q[1], q[2], q[3]) < 0) beyond = i;
    }
    if (beyond < 0) return t;
    const uint32_t n = dt->tn[4 * (size_t)t + (uint32_t)beyond];
    if (n >= I2M_DT_REMOTE || !face_in_zone(w, dt, t, beyond)) return I2M_DT_NONE;
    if (w->ctx.block && !i2m_dt_block_holds(dt, w->ctx.block, n >> 2)) return I2M_DT_NONE;
    t = n >> 2;
  }
  return I2M_DT_NONE;
}

/* Puts a vertex (global id gid, kind, its place in the grids) at p, which a tet near tet start
 * holds; *vout is its slot; its tets labelled unless `label` is false.  ROLLBACK when p lies
 * beyond the walk's reach. */
static i2m_dt_status_t put_in(perturb_t *P, const double p[3], i2m_gidx_t gid, uint8_t kind, vplace_t g, uint32_t start,
                              bool label, uint32_t *vout)
{
  i2m_refine_t *r = P->w->r;
  i2m_dt_ctx_t *ctx = &P->w->ctx;
  const uint32_t seed = locate_near(P->w, start, p);
  if (seed == I2M_DT_NONE) return I2M_DT_ROLLBACK;
  i2m_dt_status_t st = i2m_dt_insert(ctx, p, gid, kind, seed, I2M_DT_NONE, vout);
  i2m_dt_unlock_all(ctx);
  if (st != I2M_DT_OK) return st;
  if (grids_in(r, *vout, g) != I2M_OK) return I2M_DT_FAILED;
  if (dist_tracking(r) && dist_note_vertex(P->w, *vout) != I2M_OK) return I2M_DT_FAILED;
  return note_created(P, label) == I2M_OK ? I2M_DT_OK : I2M_DT_FAILED;
}

/* The changed tets that are alive, each once (a slot the trial took again is listed twice),
 * into P->extra. */
static i2m_err_t alive_changed(perturb_t *P)
{
  const i2m_dt_t *dt = P->w->r->dt;
  I2M_CALL(seen_clear(P, P->nchanged + 1));
  I2M_CALL(grow_list(&P->extra, &P->cap_extra, P->nchanged));
  P->nextra = 0;
  for (uint32_t k = 0; k < P->nchanged; k++) {
    const uint32_t t = P->changed[k];
    if (i2m_dt_alive(dt, t) && seen_add(P, t)) P->extra[P->nextra++] = t;
  }
  return I2M_OK;
}

/* May worker w (arg) read the tet across face j of tet t?  Only when the face has a vertex in
 * its zone and the tet lies in its block (else another thread or a rank may be changing it). */
static bool across_readable(const void *arg, uint32_t t, int j)
{
  const i2m_refine_worker_t *w = arg;
  const i2m_dt_t *dt = w->r->dt;
  if (!face_in_zone(w, dt, t, j)) return false;
  const uint32_t nb = dt->tn[4 * (size_t)t + j];
  return nb < I2M_DT_REMOTE && (!w->ctx.block || i2m_dt_block_holds(dt, w->ctx.block, nb >> 2));
}

/* Are the tets across the ports of `before`'s piece (the tissue's tets just outside the region
 * that its tets joined) still joined, now that the change is in, by a path of their label
 * found within WAY_ROUND tets of the first (inside the zone and the block: the tets beyond
 * may be changing)? */
static i2m_err_t way_round(perturb_t *P, const region_t *before, uint32_t piece, bool *joined)
{
  const i2m_refine_worker_t *w = P->w;
  const i2m_dt_t *dt = w->r->dt;
  I2M_CALL(grow_list(&P->extra, &P->cap_extra, before->nport)); /* (the after tets are no longer needed) */
  uint32_t *targets = P->extra, left = 0;
  for (uint32_t p = 0; p < before->nport; p++) {
    if (before->port[p].piece != piece) continue;
    bool again = false;
    for (uint32_t q = 0; q < left && !again; q++) again = targets[q] == before->port[p].across;
    if (!again) targets[left++] = before->port[p].across;
  }
  const uint32_t ntargets = left, start = targets[0], label = tinfo(dt, start)->label;
  I2M_CALL(seen_clear(P, WAY_ROUND + 4));
  I2M_CALL(grow_list(&P->queue, &P->cap_queue, WAY_ROUND + 4));
  uint32_t n = 0;
  P->queue[n++] = start;
  seen_add(P, start);
  left--;
  for (uint32_t head = 0; head < n && left > 0; head++) {
    const uint32_t t = P->queue[head];
    for (int j = 0; j < 4 && left > 0 && n < WAY_ROUND; j++) {
      if (!across_readable(w, t, j)) continue;
      const uint32_t nb = dt->tn[4 * (size_t)t + j];
      if (tinfo(dt, nb >> 2)->label != label || !seen_add(P, nb >> 2)) continue;
      P->queue[n++] = nb >> 2;
      for (uint32_t q = 1; q < ntargets; q++) left -= targets[q] == nb >> 2;
    }
  }
  *joined = left == 0;
  return I2M_OK;
}

/* Do the changed tets (labelled) keep every tissue's connections through the region they
 * fill, as it was before the change (P->before, or P->before_label)?  A region of one label
 * before and after is one piece of it both times.  Tets outside that its tets joined and
 * the new ones do not may be joined farther out (way_round). */
static i2m_err_t connections_kept(perturb_t *P, bool *keeps)
{
  const i2m_dt_t *dt = P->w->r->dt;
  I2M_CALL(alive_changed(P));
  *keeps = true;
  if (P->before_label >= 0 && region_uniform_label(dt, P->extra, P->nextra) == P->before_label) return I2M_OK;
  I2M_CALL(region_of_tets(&P->regions, dt, P->extra, P->nextra, -1, &P->now));
  if (P->before_label >= 0) { /* (the same region, its boundary faces the same) */
    I2M_CALL(region_of_tets(&P->regions, dt, P->extra, P->nextra, P->before_label, &P->was));
    P->before = &P->was;
  }
  I2M_CALL(region_keeps(&P->regions, dt, P->before, &P->now, keeps));
  if (*keeps || P->regions.nfailed == 0) return I2M_OK; /* (nfailed 0: a new portless piece) */
  for (uint32_t f = 0; f < P->regions.nfailed; f++) {
    I2M_CALL(way_round(P, P->before, P->regions.failed[f], keeps));
    if (!*keeps) break;
  }
  return I2M_OK;
}

/* connections_kept: 1 yes, 0 no (also when the scratch space could not grow: a change
 * refused is never wrong). */
static int keeps_connections(perturb_t *P)
{
  bool keeps;
  P->regions.readable = across_readable;
  P->regions.readable_arg = P->w;
  if (connections_kept(P, &keeps) != I2M_OK) return 0;
  P->cut += !keeps;
  return keeps;
}

/* Do the changed tets pass every rule, the output tets among them with their smallest
 * dihedral angle above the worst of the star's output tets (their largest cosine below
 * floor_cos)?  1 yes, 0 no, -1 the rules cannot tell inside the zone.  With angles_seen, the
 * angles passed already (trial_accept): only the rules are left.  The first `cached`
 * changed tets' cosines are P->hole_cos's (a removal's tets, the same for every trial of its
 * vertex, unless the trial took their slots).  The changed tets from `unlabelled` on get
 * their labels once the angles pass (most trials fail on the angles, and need none); a tet
 * below the floor is labelled first, to tell whether it is an output tet.  (Tets outside every
 * label do not count, either way: with them in the floor, a surface vertex whose star held an
 * outside sliver could make an output tet nearly as flat, and the second stage made tets below
 * the first stage's 5 degrees again, 82 on the liver at 6 M tets in its first round.) */
static int changed_ok(perturb_t *P, double floor_cos, bool angles_seen, uint32_t cached, uint32_t unlabelled)
{
  const i2m_dt_t *dt = P->w->r->dt;
  for (uint32_t k = 0; k < P->nchanged && !angles_seen; k++) {
    const uint32_t t = P->changed[k];
    if (!i2m_dt_alive(dt, t)) continue; /* (a removal's tet the insertion took again) */
    if (k < cached && i2m_dt_stamp(dt, t) != P->hole_meta[k]) continue; /* (its slot, a new tet's: checked below) */
    if ((k < cached ? P->hole_cos[k] : tet_badness(P->w->r, t, NULL)) < floor_cos) continue;
    if (k >= unlabelled) label_tet(P->w->r, t);
    if (tinfo(dt, t)->label != 0) return 0;
  }
  for (uint32_t k = unlabelled; k < P->nchanged; k++)
    if (i2m_dt_alive(dt, P->changed[k])) label_tet(P->w->r, P->changed[k]);
  const int joined = keeps_connections(P);
  if (joined <= 0) return joined;
  for (uint32_t k = 0; k < P->nchanged; k++) {
    const uint32_t t = P->changed[k];
    if (!i2m_dt_alive(dt, t)) continue;
    action_t a;
    const int c = classify_action(P->w, t, &a, 0);
    if (c != 0) return c > 0 ? 0 : -1;
  }
  return 1;
}

static bool worth_watching(const struct sliver_pass *S, double hi, double lo);

/* The live tets that a move made (kept or undone: undoing restores the tets, not their slots)
 * are the tets the next round looks at besides its list's.  Their angles are taken now, while
 * they are in cache (at the round's end, a third of its time went to finding them again), and
 * only the slivers and the tets worth watching are kept.  A move in place reshapes tets and
 * keeps their slots and generations: those are listed apart and looked at again at the end
 * (collect_after_round), as a later move in place may reshape them again. */
static i2m_err_t note_touched(perturb_t *P, bool in_place)
{
  const i2m_refine_t *r = P->w->r;
  const i2m_dt_t *dt = r->dt;
  const struct sliver_pass *S = r->slivers;
  if (dist_tracking(r)) return I2M_OK; /* (a task lists its tile's slivers itself) */
  if (in_place) {
    I2M_CALL(grow_list(&P->reshaped, &P->cap_reshaped, P->nreshaped + P->nchanged));
    for (uint32_t k = 0; k < P->nchanged; k++)
      if (i2m_dt_alive(dt, P->changed[k])) P->reshaped[P->nreshaped++] = P->changed[k];
    return I2M_OK;
  }
  const double cos_bound = cos(S->bound * (I2M_PI / 180.0));
  for (uint32_t k = 0; k < P->nchanged; k++) {
    const uint32_t t = P->changed[k];
    if (!i2m_dt_alive(dt, t) || !tet_kept(dt, t)) continue;
    double hi, lo;
    tet_extremes(r, t, &hi, &lo);
    if (!(badness_from(S, hi, lo) > cos_bound) && !worth_watching(S, hi, lo)) continue;
    if (P->ntouched == P->cap_touched) {
      const uint32_t c = P->cap_touched ? 2 * P->cap_touched : 1024;
      I2M_CALL(i2m_realloc(c, sizeof *P->touched, &P->touched));
      P->cap_touched = c;
    }
    P->touched[P->ntouched++] = (touched_t){t, i2m_dt_stamp(dt, t), hi, lo};
  }
  return I2M_OK;
}

static void set_xyz(i2m_dt_t *dt, uint32_t v, const double x[3]) { memcpy(dt->xyzw + 4 * (size_t)v, x, 3 * sizeof *x); }

/* Do v's tets (the changed list) lie in the same tiles with v at x0 as where it is now?  (The
 * tiles' lists and the ranks' submeshes file a tet under its centroid's tile.) */
static bool same_tiles(perturb_t *P, uint32_t v, const double x0[3])
{
  i2m_refine_t *r = P->w->r;
  if (!r->tiling) return true;
  const double *x = i2m_dt_xyz(r->dt, v);
  const double p[3] = {x[0], x[1], x[2]};
  for (uint32_t k = 0; k < P->nchanged; k++) P->saved[2 * k + 1] = tiles_tile_of_tet(r, P->changed[k]);
  set_xyz(r->dt, v, x0);
  bool same = true;
  for (uint32_t k = 0; k < P->nchanged && same; k++) same = P->saved[2 * k + 1] == tiles_tile_of_tet(r, P->changed[k]);
  set_xyz(r->dt, v, p);
  return same;
}

/* The move of v to p without a removal, when v's tets stay Delaunay with v there
 * (i2m_dt_move) and in the same tiles: they are labelled again and judged as a removal and a
 * reinsertion's would be (the same tets), and undone by moving v back.  MOVE_NOT_IN_PLACE when
 * the tets would change: nothing changed, the caller removes and reinserts. */
static int move_in_place(perturb_t *P, uint32_t v, const double x0[3], const double p[3], vplace_t g, double floor_cos)
{
  i2m_refine_t *r = P->w->r;
  i2m_dt_t *dt = r->dt;
  i2m_dt_ctx_t *ctx = &P->w->ctx;
  grids_out(r, v, g);
  const i2m_dt_status_t st = i2m_dt_move(ctx, v, p);
  i2m_dt_unlock_all(ctx);
  bool moved = st == I2M_DT_OK;
  if (moved) {
    if (grow_list(&P->changed, &P->cap_changed, ctx->nnew) != I2M_OK ||
        grow_list(&P->saved, &P->cap_saved, 2 * ctx->nnew) != I2M_OK)
      return MOVE_ERROR;
    memcpy(P->changed, ctx->newt, ctx->nnew * sizeof *P->changed);
    P->nchanged = ctx->nnew;
    if (!same_tiles(P, v, x0)) {
      set_xyz(dt, v, x0);
      moved = false;
    }
  }
  if (grids_in(r, v, g) != I2M_OK) return MOVE_ERROR;
  if (!moved) {
    P->nchanged = 0;
    return MOVE_NOT_IN_PLACE;
  }
  P->tried++;
  P->in_place++;
  P->before_label = region_uniform_label(dt, P->changed, P->nchanged);
  P->before = &P->was;
  if (P->before_label < 0 && region_of_tets(&P->regions, dt, P->changed, P->nchanged, -1, &P->was) != I2M_OK)
    return MOVE_ERROR;
  for (uint32_t k = 0; k < P->nchanged; k++) {
    P->saved[2 * k] = tinfo(dt, P->changed[k])->label;
    label_tet(r, P->changed[k]);
  }
  const int ok = changed_ok(P, floor_cos, false, 0, P->nchanged);
  if (ok > 0) {
    P->kept++;
    P->in_place_kept++;
    return note_touched(P, true) == I2M_OK ? MOVE_KEPT : MOVE_ERROR;
  }
  grids_out(r, v, g); /* back where it was: the same tets, their old labels */
  set_xyz(dt, v, x0);
  if (grids_in(r, v, g) != I2M_OK) return MOVE_ERROR;
  for (uint32_t k = 0; k < P->nchanged; k++) tinfo(dt, P->changed[k])->label = (uint16_t)P->saved[2 * k];
  P->nchanged = 0;
  return ok < 0 ? MOVE_DEFERRED : MOVE_UNDONE;
}

/* A vertex whose moves are being tried.  While it is in the mesh each target is tried in
 * place (when its tets stay); the first target that cannot be takes the vertex out, and from
 * then on each target is an insertion into the hole, undone from its journal when refused
 * (far cheaper than taking the vertex out again: the tets come back as they were, in their
 * slots); if none is kept, the vertex goes back to where it was (the same triangulation: its
 * star was the zone's, so it fits again, in slots the removal gave back). */
typedef struct {
  uint32_t v;                /* its slot, while in the mesh */
  bool out;                  /* taken out */
  double x0[3];              /* where it was */
  i2m_gidx_t gid;            /* its global id, kind and place in the grids, kept by every move */
  uint8_t kind;
  vplace_t g;
  uint32_t start, nremoved;  /* once out: a tet of the hole; the removal's tets (changed[0..)) */
} mover_t;

static void mover_begin(const i2m_refine_t *r, uint32_t v, mover_t *M)
{
  const double *x = i2m_dt_xyz(r->dt, v);
  *M = (mover_t){v, false, {x[0], x[1], x[2]}, i2m_dt_gid(r->dt, v), r->dt->vkind[v], place_of(r, v), 0, 0};
}

/* The vertex out of the mesh (its removal's tets are the changed list's start).  A MOVE_*
 * result: MOVE_KEPT here means only that it is out. */
static int mover_take_out(perturb_t *P, mover_t *M)
{
  const i2m_dt_t *dt = P->w->r->dt;
  if (star_of(P, M->v) != I2M_OK) return MOVE_ERROR;
  P->star_label = region_uniform_label(dt, P->star, P->nstar);
  if (P->star_label < 0 && region_of_tets(&P->regions, dt, P->star, P->nstar, -1, &P->star_before) != I2M_OK)
    return MOVE_ERROR;
  P->nchanged = 0;
  const i2m_dt_status_t st = take_out(P, M->v);
  if (st == I2M_DT_FAILED) return MOVE_ERROR;
  if (st != I2M_DT_OK) return st == I2M_DT_ROLLBACK || st == I2M_DT_FULL ? MOVE_DEFERRED : MOVE_UNDONE; /* nothing changed */
  M->out = true;
  M->start = P->w->ctx.newt[0];
  M->nremoved = P->nchanged;
  if (M->nremoved > P->cap_hole) {
    P->cap_hole = M->nremoved + M->nremoved / 2 + 64;
    if (i2m_realloc(P->cap_hole, sizeof *P->hole_cos, &P->hole_cos) != I2M_OK ||
        i2m_realloc(P->cap_hole, sizeof *P->hole_meta, &P->hole_meta) != I2M_OK)
      return MOVE_ERROR;
  }
  for (uint32_t k = 0; k < M->nremoved; k++) {
    P->hole_cos[k] = tet_badness(P->w->r, P->changed[k], NULL);
    P->hole_meta[k] = i2m_dt_stamp(P->w->r->dt, P->changed[k]);
  }
  return MOVE_KEPT;
}

/* Is tet t one of the hole's (the removal's tets, P->changed[0 .. nchanged) in the hook)? */
static bool in_hole(const perturb_t *P, uint32_t t)
{
  for (uint32_t k = 0; k < P->nchanged; k++)
    if (P->changed[k] == t) return true;
  return false;
}

/* The region a change of the vertex taken out replaces is its star as it was (P->star_before,
 * or the one label P->star_label). */
static void before_is_star(perturb_t *P)
{
  P->before_label = P->star_label;
  P->before = &P->star_before;
}

/* The region an accepted trial changes, as it is before (P->before): the cavity's tets for a
 * new point; for a vertex moved, its star before the removal, grown by the cavity's tets
 * beyond the hole when there are any (the hole's tets were never in the mesh that counts). */
static i2m_err_t region_before_trial(perturb_t *P, const i2m_dt_ctx_t *ctx)
{
  const i2m_dt_t *dt = P->w->r->dt;
  if (!P->nchanged) {
    P->before_label = region_uniform_label(dt, ctx->cav, ctx->ncav);
    P->before = &P->was;
    return P->before_label >= 0 ? I2M_OK : region_of_tets(&P->regions, dt, ctx->cav, ctx->ncav, -1, &P->was);
  }
  uint32_t in_cavity = 0;
  for (uint32_t k = 0; k < P->nchanged; k++) in_cavity += i2m_dt_meta(dt, P->changed[k]) != P->hole_meta[k];
  before_is_star(P);
  if (in_cavity == ctx->ncav) return I2M_OK;
  I2M_CALL(grow_list(&P->extra, &P->cap_extra, ctx->ncav));
  P->nextra = 0;
  for (uint32_t k = 0; k < ctx->ncav; k++)
    if (!in_hole(P, ctx->cav[k])) P->extra[P->nextra++] = ctx->cav[k];
  if (P->star_label >= 0) { /* the star summed up now, from the hole's tets that fill it */
    I2M_CALL(region_of_tets(&P->regions, dt, P->changed, P->nchanged, P->star_label, &P->star_before));
    P->star_label = -1;
  }
  P->before_label = -1;
  P->before = &P->was;
  return region_grow(&P->regions, dt, &P->star_before, P->extra, P->nextra, P->changed, P->nchanged, &P->was);
}

/* Would a facet of an insertion's tets with vertices x, between tets of labels la and lb, be
 * refined: is it restricted (la != lb) with a vertex off the interfaces (R6), or, with all
 * three on them (on_interfaces), an angle below the facet bound (R5)? */
static bool facet_refined(const i2m_refine_t *r, const double *const x[3], bool on_interfaces, int la, int lb)
{
  return la != lb && (!on_interfaces || facet_angle_bad(r, x));
}

/* The label of the new tet across edge (a, b) of cavity face k from the tet on face k (the
 * face with the reversed edge), or -1 when none is found. */
static int label_across_edge(const perturb_t *P, const i2m_dt_ctx_t *ctx, uint32_t k, uint32_t a, uint32_t b)
{
  for (uint32_t q = 0; q < ctx->nbnd; q++) {
    if (q == k) continue;
    uint32_t f[3];
    i2m_dt_cavity_face(ctx, q, f);
    for (int i = 0; i < 3; i++)
      if (f[i] == b && f[(i + 1) % 3] == a) return P->new_label[q];
  }
  return -1;
}

/* Do the tets an insertion at p would make pass the rules that can be judged before it is
 * made (classify_action judges them after it, and a refusal then costs the insertion and its
 * undoing: a fifth of the trials came that far to fail a rule)?  Each new tet's ratio and
 * size (R3, R4), and its restricted facets (facet_refined): those across the cavity's
 * boundary, whose outer side's label is known, and those through p, between two new tets.
 * The new tets' labels go to P->new_label, in the order of the cavity's faces. */
static bool rules_may_pass(perturb_t *P, const i2m_dt_ctx_t *ctx, const double p[3])
{
  const i2m_refine_t *r = P->w->r;
  const i2m_dt_t *dt = r->dt;
  if (ctx->nbnd > P->cap_new_label) {
    const uint32_t c = ctx->nbnd + ctx->nbnd / 2 + 64;
    if (i2m_realloc(c, sizeof *P->new_label, &P->new_label) != I2M_OK) return false; /* (refused: never wrong) */
    P->cap_new_label = c;
  }
  for (uint32_t k = 0; k < ctx->nbnd; k++) /* (the outer tets' labels: asked for now, read below) */
    if (ctx->bnd[k].out != I2M_DT_NONE) I2M_PREFETCH(tinfo(dt, ctx->bnd[k].out >> 2));
  bool one_label = true;
  for (uint32_t k = 0; k < ctx->nbnd; k++) {
    uint32_t abc[3];
    i2m_dt_cavity_face(ctx, k, abc);
    const double *x[4] = {i2m_dt_xyz(dt, abc[0]), i2m_dt_xyz(dt, abc[1]), i2m_dt_xyz(dt, abc[2]), p};
    bool volume_fires;
    const int label = centre_label_volume(r, x, &volume_fires);
    if (volume_fires) return false;
    P->new_label[k] = (uint16_t)label;
    one_label &= label == P->new_label[0];
    const uint32_t out = ctx->bnd[k].out;
    const bool on_interfaces = dt->vkind[abc[0]] == I2M_VK_SURFACE && dt->vkind[abc[1]] == I2M_VK_SURFACE &&
                               dt->vkind[abc[2]] == I2M_VK_SURFACE;
    if (out != I2M_DT_NONE && facet_refined(r, x, on_interfaces, label, tinfo(dt, out >> 2)->label)) return false;
  }
  if (one_label) return true; /* (no facet through p is restricted) */
  const bool p_surface = P->trial_kind == I2M_VK_SURFACE;
  for (uint32_t k = 0; k < ctx->nbnd; k++) { /* each facet through p, from the side where a < b */
    uint32_t abc[3];
    i2m_dt_cavity_face(ctx, k, abc);
    for (int i = 0; i < 3; i++) {
      const uint32_t a = abc[i], b = abc[(i + 1) % 3];
      if (a > b) continue;
      const double *x[3] = {i2m_dt_xyz(dt, a), i2m_dt_xyz(dt, b), p};
      const bool on_interfaces = p_surface && dt->vkind[a] == I2M_VK_SURFACE && dt->vkind[b] == I2M_VK_SURFACE;
      if (on_interfaces && !facet_angle_bad(r, x)) continue; /* (restricted or not, it passes) */
      const int across = label_across_edge(P, ctx, k, a, b);
      if (across >= 0 && facet_refined(r, x, on_interfaces, P->new_label[k], across)) return false;
    }
  }
  return true;
}

/* The new tet of a trial on face k of its cavity: false when it would be an output tet (a label
 * at its centre) no better than the floor.  Asked during the search too (accept_face): most
 * trials fail here, and a failure found early saves the rest of the search. */
static bool trial_face_ok(void *arg, const i2m_dt_ctx_t *ctx, uint32_t k, const double p[3])
{
  const perturb_t *P = arg;
  const i2m_refine_t *r = P->w->r;
  uint32_t abc[3];
  i2m_dt_cavity_face(ctx, k, abc);
  const double *x[4] = {i2m_dt_xyz(r->dt, abc[0]), i2m_dt_xyz(r->dt, abc[1]), i2m_dt_xyz(r->dt, abc[2]), p};
  return !(as_bad_as(r->slivers, x, P->trial_floor) && centre_label(r, x) != 0);
}

/* The insertion hook of a trial: the first test of changed_ok, on the tets the insertion would
 * leave and make, before it changes anything (most trials fail there: an insertion undone
 * costs as much again).  False when an output tet among them would not beat the floor. */
static bool trial_accept(void *arg, const i2m_dt_ctx_t *ctx, const double p[3])
{
  perturb_t *P = arg;
  const i2m_dt_t *dt = P->w->r->dt;
  /* the removal's tets that stay (the list holds only them yet; a tet of this insertion's
   * cavity carries the mark, so its meta word differs from the stamp recorded) */
  for (uint32_t k = 0; k < P->nchanged; k++) {
    const uint32_t t = P->changed[k];
    if (i2m_dt_meta(dt, t) != P->hole_meta[k] || P->hole_cos[k] < P->trial_floor) continue;
    if (tinfo(dt, t)->label != 0) return false;
  }
  for (uint32_t k = ctx->nbnd_seen; k < ctx->nbnd; k++) /* (those the search did not show trial_face_ok) */
    if (!trial_face_ok(P, ctx, k, p)) return false;
  if (!rules_may_pass(P, ctx, p)) {
    P->prejudged++;
    return false;
  }
  return region_before_trial(P, ctx) == I2M_OK;
}

/* The vertex (out) at p, on trial: journaled, so that a refusal undoes it, and refused before
 * it goes in when the angles already fail (trial_accept). */
static i2m_dt_status_t put_in_trial(perturb_t *P, const mover_t *M, const double p[3], double floor_cos, uint32_t *moved)
{
  i2m_dt_ctx_t *ctx = &P->w->ctx;
  P->nchanged = M->nremoved;
  P->trial_floor = floor_cos;
  P->trial_kind = M->kind;
  ctx->journal = true;
  ctx->accept = trial_accept;
  ctx->accept_face = trial_face_ok;
  ctx->accept_arg = P;
  const i2m_dt_status_t st = put_in(P, p, M->gid, M->kind, M->g, M->start, false, moved);
  ctx->journal = false;
  ctx->accept = NULL;
  ctx->accept_face = NULL;
  return st;
}

/* A refused trial undone: the vertex out of its grids, its tets and itself out of the lists of
 * what the task made (dist), the hole's tets back. */
static i2m_err_t undo_trial(perturb_t *P, const mover_t *M, uint32_t moved, uint32_t nborn, uint32_t nbornv)
{
  i2m_refine_worker_t *w = P->w;
  grids_out(w->r, moved, M->g);
  w->nborn = nborn;
  w->nbornv = nbornv;
  P->nchanged = M->nremoved;
  return i2m_dt_undo_insert(&w->ctx);
}

/* One target p for the vertex (the same kind, global id and patch): kept when the changed tets
 * pass.  A MOVE_* result. */
static int try_target(perturb_t *P, mover_t *M, const double p[3], double floor_cos)
{
  if (!M->out) {
    const int in_place = move_in_place(P, M->v, M->x0, p, M->g, floor_cos); /* (a fraction of the cost, when it can) */
    if (in_place != MOVE_NOT_IN_PLACE) return in_place;
    const int out = mover_take_out(P, M);
    if (out != MOVE_KEPT) return out;
  }
  P->tried++;
  const uint32_t nborn = P->w->nborn, nbornv = P->w->nbornv;
  uint32_t moved;
  const i2m_dt_status_t st = put_in_trial(P, M, p, floor_cos, &moved);
  if (st == I2M_DT_FAILED) return MOVE_ERROR;
  if (st != I2M_DT_OK) return st == I2M_DT_ROLLBACK || st == I2M_DT_FULL ? MOVE_DEFERRED : MOVE_UNDONE; /* not in */
  const i2m_dt_ctx_t *ctx = &P->w->ctx; /* (the hole's tets were labelled when it was made) */
  for (uint32_t k = 0; k < ctx->nnew; k++) tinfo(P->w->r->dt, ctx->newt[k])->label = P->new_label[k];
  const int ok = changed_ok(P, floor_cos, true, M->nremoved, P->nchanged);
  if (ok > 0) {
    P->kept++;
    M->v = moved;
    M->out = false;
    return note_touched(P, false) == I2M_OK ? MOVE_KEPT : MOVE_ERROR;
  }
  if (undo_trial(P, M, moved, nborn, nbornv) != I2M_OK) return MOVE_ERROR;
  return ok < 0 ? MOVE_DEFERRED : MOVE_UNDONE;
}

/* The vertex (out) left out for good: kept when the tets that fill its hole pass as a move's
 * tets would (changed_ok).  A MOVE_* result. */
static int try_drop(perturb_t *P, mover_t *M, double floor_cos)
{
  P->tried++;
  P->nchanged = M->nremoved;
  before_is_star(P);
  const int ok = changed_ok(P, floor_cos, false, M->nremoved, M->nremoved);
  if (ok <= 0) return ok < 0 ? MOVE_DEFERRED : MOVE_UNDONE;
  P->kept++;
  P->dropped++;
  M->out = false;
  return note_touched(P, false) == I2M_OK ? MOVE_KEPT : MOVE_ERROR;
}

/* A wide round's first try for a vertex of a sliver: the vertex taken out of the mesh, and
 * left out if that passes (try_drop; its targets start with its removal anyway).  On the knee
 * at 6 M tets, a sliver of four surface vertices (three on a plane of voxel faces, one just
 * off it) at 12.9 degrees refused every insertion and every move, and went with one of them. */
static int drop_first(perturb_t *P, mover_t *M, double floor_cos)
{
  const int out = mover_take_out(P, M);
  return out == MOVE_KEPT ? try_drop(P, M, floor_cos) : out;
}

/* After the vertex's targets: back where it was, if none was kept. */
static int mover_end(perturb_t *P, mover_t *M)
{
  if (!M->out) return MOVE_UNDONE;
  P->nchanged = M->nremoved;
  if (put_in(P, M->x0, M->gid, M->kind, M->g, M->start, true, &M->v) != I2M_DT_OK) return MOVE_ERROR;
  M->out = false;
  return note_touched(P, false) == I2M_OK ? MOVE_UNDONE : MOVE_ERROR;
}

/* A surface vertex stays on its interface patch: p becomes the closest interface point to p,
 * when that lies on the same patch (false otherwise). */
static bool onto_patch(const i2m_refine_t *r, uint32_t patch, double p[3])
{
  i2m_edt_probe_t pr;
  i2m_edt_probe_world(r->edt, p, INFINITY, &pr);
  if (!isfinite(pr.d2) || patch_key(pr.pair[0], pr.pair[1]) != patch) return false;
  memcpy(p, pr.z, sizeof pr.z);
  return true;
}

/* The tet whose vertices are the slots v[0..3] (in any order), from the star of v[a] (a
 * vertex of the zone: nobody else changes its tets); I2M_DT_NONE when they make none. */
static uint32_t tet_of_vertices(perturb_t *P, const uint32_t v[4], int a)
{
  const i2m_dt_t *dt = P->w->r->dt;
  if (star_of(P, v[a]) != I2M_OK) return I2M_DT_NONE;
  for (uint32_t k = 0; k < P->nstar; k++) {
    const uint32_t *tv = dt->tv + 4 * (size_t)P->star[k];
    int found = 0;
    for (int i = 0; i < 4; i++)
      for (int j = 0; j < 4; j++) found += j != a && tv[i] == v[j];
    if (found == 3) return P->star[k];
  }
  return I2M_DT_NONE;
}

/* A fresh global id for a point the pass inserts: the next of its tile's, or, in the
 * sequential part (worker 0 alone, slivers in a fixed order), the next of the pass's own range
 * (the tiling's ids after its last tile's): the same ids whatever the number of threads. */
static i2m_gidx_t fresh_gid(const i2m_refine_worker_t *w)
{
  return w->tile ? w->tile->gid_next : w->r->slivers->seq_gid;
}

static void gid_taken(i2m_refine_worker_t *w)
{
  if (w->tile) w->tile->gid_next++;
  else w->r->slivers->seq_gid++;
}

/* A new vertex for sliver s near c: with `snap`, the interface point closest to c when that
 * lies within delta of it (a surface vertex of that patch: *snapped), else c (a free vertex);
 * a trial as a vertex move's (try_target: a mover that is out and removed nothing), kept when
 * the new tets pass every rule and the output ones beat the floor.  A MOVE_* result. */
static int insert_at(perturb_t *P, const sliver_t *s, const double c[3], double floor_cos, bool snap, bool *snapped)
{
  i2m_refine_worker_t *w = P->w;
  i2m_refine_t *r = w->r;
  i2m_edt_probe_t pr;
  i2m_edt_probe_world(r->edt, c, INFINITY, &pr);
  mover_t M = {0, true, {c[0], c[1], c[2]}, fresh_gid(w), I2M_VK_FREE, {false, false, 0}, s->t, 0};
  *snapped = snap && isfinite(pr.d2) && pr.d2 < r->delta2;
  if (*snapped) {
    memcpy(M.x0, pr.z, sizeof M.x0);
    M.kind = I2M_VK_SURFACE;
    M.g = (vplace_t){true, false, patch_key(pr.pair[0], pr.pair[1])};
  } else {
    M.g.near = isfinite(pr.d2) && pr.d2 <= r->four_delta2;
  }
  if (!tiles_zone_holds(w, M.x0)) return MOVE_DEFERRED;
  const int got = try_target(P, &M, M.x0, floor_cos);
  if (got == MOVE_KEPT) {
    gid_taken(w);
    P->inserted++;
  }
  return got;
}

/* insert_at p, snapped to the interface when near it; in a wide round, when that is refused,
 * p where it is too (a sliver of surface vertices whose every point on the interface fails
 * may take a free one). */
static int insert_near(perturb_t *P, const sliver_t *s, const double p[3], double floor_cos, bool wide)
{
  bool snapped;
  const int got = insert_at(P, s, p, floor_cos, true, &snapped);
  if (!wide || !snapped || got == MOVE_KEPT || got == MOVE_ERROR) return got;
  return insert_at(P, s, p, floor_cos, false, &snapped);
}

/* A new vertex in sliver s's circumball (insert_near): at its circumcentre, else at up to PICKS
 * random points of its picking region (the ball of PICK_RADIUS times the circumradius around
 * the circumcentre, Li-Teng), until one is kept.  A refused point costs a cavity search
 * (trial_accept), far less than a vertex move's removal.  A MOVE_* result. */
static int try_insertion(perturb_t *P, const sliver_t *s)
{
  tet_geom_t g;
  tet_centre(P->w->r, s->t, &g);
  if (!isfinite(g.r2)) return MOVE_UNDONE;
  const double floor_cos = floor_of(P->w->r, tet_badness(P->w->r, s->t, NULL));
  const bool wide = P->w->r->slivers->wide;
  const double reach = (wide ? WIDE_PICK_RADIUS : PICK_RADIUS) * sqrt(g.r2);
  const int picks = wide ? WIDE_PICKS : PICKS;
  int got = insert_near(P, s, g.cc, floor_cos, wide);
  for (int k = 0; k < picks && got != MOVE_KEPT && got != MOVE_ERROR; k++) {
    double d[3];
    random_in_ball(&P->rng, d, 0.0);
    const double p[3] = {g.cc[0] + reach * d[0], g.cc[1] + reach * d[1], g.cc[2] + reach * d[2]};
    got = insert_near(P, s, p, floor_cos, wide);
  }
  return got;
}

/* Tries to move each vertex of sliver s (free vertices anywhere near, surface vertices along
 * their patch), the free ones first, each kind in the order of their global ids, until one
 * move is kept.  A MOVE_* result (MOVE_DEFERRED: some move could not stay in the zone, none
 * was kept).  A deferred sliver's tet is then the one its vertices make now: moves tried and
 * undone rebuild it in other slots, and the sequential pass must find it (else it would skip
 * the sliver as changed, and a sliver whose moves always leave the zone would never be
 * treated). */
static int treat_sliver(perturb_t *P, sliver_t *s)
{
  i2m_refine_worker_t *w = P->w;
  i2m_dt_t *dt = w->r->dt;
  if (i2m_dt_stamp(dt, s->t) != s->meta) return MOVE_UNDONE; /* changed by an earlier move */
  const int inserted = try_insertion(P, s);
  if (inserted == MOVE_KEPT || inserted == MOVE_ERROR) return inserted;
  uint32_t verts[4];
  i2m_gidx_t gid[4];
  memcpy(verts, dt->tv + 4 * (size_t)s->t, sizeof verts);
  /* the free vertices first (they move anywhere), then the surface vertices, each in the
   * order of their global ids */
  for (int i = 0; i < 4; i++) gid[i] = i2m_dt_gid(dt, verts[i]) + ((i2m_gidx_t)(dt->vkind[verts[i]] != I2M_VK_FREE) << 62);
  sort4_gid(gid, verts);
  int result = MOVE_UNDONE, moved = -1; /* moved: a vertex whose moves were tried */
  for (int i = 0; i < 4; i++) {
    uint32_t v = verts[i];
    const bool surface = dt->vkind[v] == I2M_VK_SURFACE;
    if (!surface && dt->vkind[v] != I2M_VK_FREE) continue;
    if (!tiles_zone_holds(w, i2m_dt_xyz(dt, v))) {
      result = MOVE_DEFERRED;
      continue;
    }
    if (star_of(P, v) != I2M_OK) return MOVE_ERROR;
    double floor_cos = -1.0, lmin2 = INFINITY; /* the worst angle of the star's output tets, as its cosine */
    const double *x = i2m_dt_xyz(dt, v);
    for (uint32_t k = 0; k < P->nstar; k++) {
      const uint32_t t = P->star[k], *tv = dt->tv + 4 * (size_t)t;
      if (tet_kept(dt, t)) {
        const double c = tet_badness(w->r, t, NULL);
        floor_cos = c > floor_cos ? c : floor_cos;
      }
      for (int j = 0; j < 4; j++)
        if (tv[j] != v && tv[j] >= 8) { /* (box corners are far) */
          const double d2 = i2m_dist2(x, i2m_dt_xyz(dt, tv[j]));
          lmin2 = d2 < lmin2 ? d2 : lmin2;
        }
    }
    if (!isfinite(lmin2)) continue;
    const double lmin = sqrt(lmin2);
    floor_cos = floor_of(w->r, floor_cos);
    mover_t M;
    mover_begin(w->r, v, &M);
    const bool wide = w->r->slivers->wide;
    if (wide) {
      const int got = drop_first(P, &M, floor_cos);
      if (got == MOVE_KEPT || got == MOVE_ERROR) return got;
      if (got == MOVE_DEFERRED) result = MOVE_DEFERRED;
      if (M.out) moved = i;
    }
    const int targets = wide ? WIDE_MOVES : MOVES_PER_VERTEX;
    const double reach = wide ? WIDE_REACH : REACH;
    for (int m = 0; m < targets; m++) {
      /* a random direction, at a distance from NEAR to `reach` times the shortest edge */
      double d[3];
      const double n2 = random_in_ball(&P->rng, d, 1e-6);
      const double len = lmin * (NEAR + (reach - NEAR) * uniform01(&P->rng)) / sqrt(n2);
      double p[3] = {M.x0[0] + len * d[0], M.x0[1] + len * d[1], M.x0[2] + len * d[2]};
      if (surface && !onto_patch(w->r, M.g.tag, p)) continue;
      const int got = try_target(P, &M, p, floor_cos);
      moved = i;
      if (got == MOVE_KEPT || got == MOVE_ERROR) return got;
      if (got == MOVE_DEFERRED) result = MOVE_DEFERRED;
    }
    if (mover_end(P, &M) == MOVE_ERROR) return MOVE_ERROR;
    verts[i] = M.v; /* (its slot after the moves undone) */
  }
  if (result == MOVE_DEFERRED && moved >= 0) { /* (no move tried: the tet is as it was) */
    const uint32_t t = tet_of_vertices(P, verts, moved);
    if (t != I2M_DT_NONE) {
      s->t = t;
      s->meta = i2m_dt_stamp(dt, t);
    }
  }
  return result;
}

/* ---- the lists of slivers ---- */

/* Output tet t, whose badness (tet_badness) is c, joins the list when it is worse than the
 * bound (c above cos_bound). */
static i2m_err_t consider(const i2m_dt_t *dt, uint32_t t, double c, double cos_bound, sliver_list_t *L)
{
  if (!(c > cos_bound)) return I2M_OK;
  sliver_t s = {t, i2m_dt_stamp(dt, t), i2m_degrees_of_cosine(c), {0}};
  uint32_t v[4];
  memcpy(v, dt->tv + 4 * (size_t)t, sizeof v);
  for (int i = 0; i < 4; i++) s.gid[i] = i2m_dt_gid(dt, v[i]);
  sort4_gid(s.gid, v);
  return list_push(L, &s);
}

/* ---- the watched tets (one process) ---- */

static bool worth_watching(const struct sliver_pass *S, double hi, double lo)
{
  return hi > S->cos_watch || S->cap_shift - lo > S->cos_final;
}

static i2m_err_t watch_push(watch_list_t *W, watched_t e)
{
  if (W->n == W->cap) {
    const size_t c = W->cap ? 2 * W->cap : 1024;
    I2M_CALL(i2m_realloc(c, sizeof *W->a, &W->a));
    W->cap = c;
  }
  W->a[W->n++] = e;
  return I2M_OK;
}

/* Is the entry the tet as it is now?  (An entry of a tet changed since was followed by one of
 * the change's round, if the tet was still worth a look; a move in place keeps the slot's
 * generation, hence the round of the last one, which the entries before it are older than.) */
static bool watch_valid(const i2m_refine_t *r, const watched_t *e)
{
  const struct sliver_pass *S = r->slivers;
  const uint32_t last = e->t < S->nchanged_in ? S->changed_in[e->t] : 0;
  return e->round >= last && i2m_dt_stamp(r->dt, e->t) == e->meta && tet_kept(r->dt, e->t);
}

/* A stage's list from the watched tets (the stale entries dropped): the list a pass over the
 * mesh would give, as every output tet worse than a stage's bound is watched. */
static i2m_err_t list_from_watch(const i2m_refine_t *r, struct sliver_pass *S)
{
  const double cos_bound = cos(S->bound * (I2M_PI / 180.0));
  size_t n = 0;
  S->list.n = 0;
  for (size_t k = 0; k < S->watch.n; k++) {
    const watched_t e = S->watch.a[k];
    if (!watch_valid(r, &e)) continue;
    S->watch.a[n++] = e;
    I2M_CALL(consider(r->dt, e.t, badness_from(S, e.hi, e.lo), cos_bound, &S->list));
  }
  S->watch.n = n;
  if (S->list.n > 1) qsort(S->list.a, S->list.n, sizeof *S->list.a, cmp_sliver);
  return I2M_OK;
}

/* The closing figures (collect_all's) from the watched tets; false when no tet is watched for
 * its smallest angle (every one above the bound plus the margin): then only a pass tells the
 * smallest angle. */
static bool figures_from_watch(const i2m_refine_t *r, double bound, double *min_all, int64_t *nbelow)
{
  const struct sliver_pass *S = r->slivers;
  const double cos_bound = cos(bound * (I2M_PI / 180.0));
  double m = -1.0;
  int64_t below = 0;
  for (size_t k = 0; k < S->watch.n; k++) {
    const watched_t *e = &S->watch.a[k];
    if (!watch_valid(r, e)) continue;
    m = e->hi > m ? e->hi : m;
    below += e->hi > cos_bound;
  }
  if (!(m > S->cos_watch)) return false;
  *min_all = i2m_degrees_of_cosine(m);
  *nbelow = below;
  return true;
}

#define COLLECT_CHUNKS 64

/* The output tets worse than the bound (tet_badness), in order; the smallest angle of all
 * output tets, the number of those whose smallest angle is below the bound (nbelow, if not
 * NULL), the tets worth watching (into W, if not NULL) and the dihedral bands (into bands, if
 * not NULL): fixed chunks of the slots in parallel, joined in chunk order, then sorted (the
 * same list on any number of threads). */
static i2m_err_t collect_all(const i2m_refine_t *r, double bound, sliver_list_t *L, double *min_all, int64_t *nbelow,
                             watch_list_t *W, i2m_dihedral_bands_t *bands)
{
  const struct sliver_pass *S = r->slivers;
  const i2m_dt_t *dt = r->dt;
  const uint32_t nt = i2m_dt_ntets_slots(dt);
  const double cos_bound = cos(bound * (I2M_PI / 180.0));
  sliver_list_t part[COLLECT_CHUNKS];
  watch_list_t wpart[COLLECT_CHUNKS];
  i2m_dihedral_bands_t bpart[COLLECT_CHUNKS];
  double maxc[COLLECT_CHUNKS];
  int64_t below = 0;
  memset(part, 0, sizeof part);
  memset(wpart, 0, sizeof wpart);
  memset(bpart, 0, sizeof bpart);
  int failed = 0;
  I2M_OMP(omp parallel for schedule(dynamic, 1) reduction(| : failed) reduction(+ : below))
  for (int c = 0; c < COLLECT_CHUNKS; c++) {
    const uint32_t lo = (uint32_t)((uint64_t)nt * (uint64_t)c / COLLECT_CHUNKS);
    const uint32_t hi = (uint32_t)((uint64_t)nt * (uint64_t)(c + 1) / COLLECT_CHUNKS);
    maxc[c] = -1.0;
    for (uint32_t t = lo; t < hi && !failed; t++) {
      if (!tet_kept(dt, t)) continue;
      double cs[6], chi, clo;
      tet_cosines(r, t, cs);
      extremes_of(cs, &chi, &clo);
      if (bands) i2m_dihedral_bands_add(&bpart[c], cs);
      maxc[c] = chi > maxc[c] ? chi : maxc[c];
      below += chi > cos_bound;
      failed |= consider(dt, t, badness_from(S, chi, clo), cos_bound, &part[c]) != I2M_OK;
      if (W && worth_watching(S, chi, clo))
        failed |= watch_push(&wpart[c], (watched_t){t, i2m_dt_stamp(dt, t), 0, chi, clo}) != I2M_OK;
    }
  }
  if (nbelow) *nbelow = below;
  L->n = 0;
  double m = -1.0;
  if (bands) memset(bands, 0, sizeof *bands);
  for (int c = 0; c < COLLECT_CHUNKS; c++) {
    if (bands) i2m_dihedral_bands_merge(bands, &bpart[c]);
    for (size_t i = 0; i < part[c].n && !failed; i++) failed |= list_push(L, &part[c].a[i]) != I2M_OK;
    for (size_t i = 0; W && i < wpart[c].n && !failed; i++) failed |= watch_push(W, wpart[c].a[i]) != I2M_OK;
    i2m_free(&part[c].a);
    i2m_free(&wpart[c].a);
    m = maxc[c] > m ? maxc[c] : m;
  }
  I2M_CHECK(!failed, I2M_ERR_MEMORY, "out of memory listing the slivers");
  *min_all = m > -1.0 ? i2m_degrees_of_cosine(m) : 180.0;
  if (L->n > 1) qsort(L->a, L->n, sizeof *L->a, cmp_sliver);
  return I2M_OK;
}

/* The slots of the tets the moves in place reshaped this round (each once, in seen_bits). */
static i2m_err_t reshaped_of_round(i2m_refine_t *r, struct sliver_pass *S, uint32_t **out, uint32_t *n)
{
  perturb_t *P0 = &S->per[0];
  for (int k = 1; k < r->nworkers; k++) { /* every thread's into worker 0's */
    perturb_t *P = &S->per[k];
    I2M_CALL(grow_list(&P0->reshaped, &P0->cap_reshaped, P0->nreshaped + P->nreshaped));
    if (P->nreshaped) memcpy(P0->reshaped + P0->nreshaped, P->reshaped, P->nreshaped * sizeof *P->reshaped);
    P0->nreshaped += P->nreshaped;
    P->nreshaped = 0;
  }
  uint32_t m = 0;
  for (uint32_t k = 0; k < P0->nreshaped; k++) {
    const uint32_t t = P0->reshaped[k];
    const uint64_t bit = (uint64_t)1 << (t & 63);
    if (S->seen_bits[t >> 6] & bit) continue;
    S->seen_bits[t >> 6] |= bit;
    P0->reshaped[m++] = t;
  }
  P0->nreshaped = 0;
  *out = P0->reshaped;
  *n = m;
  return I2M_OK;
}

/* The list after a round, without a pass over the mesh: a tet no change made has its angle
 * still, so the slivers left are the list's untouched ones (same slot generation) and those
 * among the tets the changes made (note_touched: each slot once, the tets reshaped in place
 * looked at anew); the made ones worth watching are watched, as of this round.  (A list
 * entry of a tet reshaped in place stays too, as before: dropping it changed the pass's path,
 * and the abdominal atlas at one thread then ended with 4 tets stuck at 12.9 degrees.) */
static i2m_err_t collect_after_round(i2m_refine_t *r, struct sliver_pass *S)
{
  const i2m_dt_t *dt = r->dt;
  sliver_list_t *L = &S->list;
  const size_t slots = i2m_dt_ntets_slots(dt), words = slots / 64 + 1;
  if (words > S->nseen_bits) { /* (a bit per slot: each once; the list is sorted below) */
    i2m_free(&S->seen_bits);
    I2M_CALL(i2m_calloc(words, sizeof *S->seen_bits, &S->seen_bits));
    S->nseen_bits = words;
  }
  if (slots > S->nchanged_in) {
    I2M_CALL(i2m_realloc(slots, sizeof *S->changed_in, &S->changed_in));
    memset(S->changed_in + S->nchanged_in, 0, (slots - S->nchanged_in) * sizeof *S->changed_in);
    S->nchanged_in = slots;
  }
  _Static_assert(3 * ROUNDS + 1 < 256, "a round's stamp fits a byte"); /* (3 stages of ROUNDS at most) */
  const uint8_t stamp = (uint8_t)(S->round + 1);
  const double cos_bound = cos(S->bound * (I2M_PI / 180.0));
  uint32_t *reshaped, nreshaped;
  I2M_CALL(reshaped_of_round(r, S, &reshaped, &nreshaped));
  size_t n = 0;
  for (size_t k = 0; k < L->n; k++) {
    const uint32_t t = L->a[k].t;
    if (i2m_dt_stamp(dt, t) == L->a[k].meta) L->a[n++] = L->a[k];
  }
  L->n = n;
  i2m_err_t err = I2M_OK;
  for (uint32_t k = 0; k < nreshaped && err == I2M_OK; k++) { /* (their older entries: stale) */
    const uint32_t t = reshaped[k];
    S->changed_in[t] = stamp;
    if (!tet_kept(dt, t)) continue;
    double hi, lo;
    tet_extremes(r, t, &hi, &lo);
    err = consider(dt, t, badness_from(S, hi, lo), cos_bound, L);
    if (err == I2M_OK && worth_watching(S, hi, lo))
      err = watch_push(&S->watch, (watched_t){t, i2m_dt_stamp(dt, t), stamp, hi, lo});
  }
  for (int w = 0; w < r->nworkers && err == I2M_OK; w++) {
    perturb_t *P = &S->per[w];
    for (uint32_t k = 0; k < P->ntouched && err == I2M_OK; k++) {
      const touched_t e = P->touched[k];
      const uint64_t bit = (uint64_t)1 << (e.t & 63);
      if ((S->seen_bits[e.t >> 6] & bit) || i2m_dt_stamp(dt, e.t) != e.meta) continue; /* (changed again since) */
      S->seen_bits[e.t >> 6] |= bit;
      err = consider(dt, e.t, badness_from(S, e.hi, e.lo), cos_bound, L);
      if (err == I2M_OK && worth_watching(S, e.hi, e.lo))
        err = watch_push(&S->watch, (watched_t){e.t, e.meta, stamp, e.hi, e.lo});
    }
  }
  for (uint32_t k = 0; k < nreshaped; k++) S->seen_bits[reshaped[k] >> 6] = 0;
  for (int w = 0; w < r->nworkers; w++) {
    perturb_t *P = &S->per[w];
    for (uint32_t k = 0; k < P->ntouched; k++) S->seen_bits[P->touched[k].t >> 6] = 0;
    P->ntouched = 0;
  }
  I2M_CALL(err);
  if (L->n > 1) qsort(L->a, L->n, sizeof *L->a, cmp_sliver);
  return I2M_OK;
}

/* ---- the pass: begin, per round the colours' phases and a sequential pass, end ---- */

static void pass_free(i2m_refine_t *r)
{
  struct sliver_pass *S = r->slivers;
  if (!S) return;
  for (int k = 0; S->per && k < r->nworkers; k++) {
    perturb_t *P = &S->per[k];
    i2m_free(&P->star);
    i2m_free(&P->seen);
    i2m_free(&P->seen_stamp);
    i2m_free(&P->changed);
    i2m_free(&P->hole_cos);
    i2m_free(&P->hole_meta);
    i2m_free(&P->saved);
    i2m_free(&P->touched);
    i2m_free(&P->reshaped);
    i2m_free(&P->new_label);
    i2m_free(&P->deferred.a);
    i2m_free(&P->inner.a);
    i2m_free(&P->stale);
    region_free(&P->star_before);
    region_free(&P->was);
    region_free(&P->now);
    i2m_free(&P->extra);
    i2m_free(&P->queue);
    region_scratch_free(&P->regions);
  }
  i2m_free(&S->per);
  i2m_free(&S->list.a);
  i2m_free(&S->seen_bits);
  i2m_free(&S->watch.a);
  i2m_free(&S->changed_in);
  i2m_free(&S->first);
  i2m_free(&S->by_tile);
  i2m_free(&S->active);
  for (uint32_t i = 0; S->cache && i < S->ncache; i++) i2m_free(&S->cache[i].a);
  i2m_free(&S->cache);
  i2m_free(&S->cache_ok);
  i2m_free(&r->slivers);
}

/* The moves tried and kept so far, over every worker. */
static void moves_so_far(const i2m_refine_t *r, const struct sliver_pass *S, int64_t *tried, int64_t *kept)
{
  *tried = *kept = 0;
  for (int k = 0; k < r->nworkers; k++) {
    *tried += S->per[k].tried;
    *kept += S->per[k].kept;
  }
}

/* When the stage is over and the bound asked for is higher, the next stage lists the tets
 * below it; after the stage at the bound asked for, the last one (caps) lists the tets worse
 * than it by tet_badness.  (With a high bound from the start, the many mild slivers would take the rounds
 * and leave the worst as they were: the smallest angle came out lower at 10 degrees than at
 * 5.  A kept move never lowers the smallest angle, so the second stage keeps the first's.) */
static i2m_err_t next_stage_if_done(i2m_refine_t *r, struct sliver_pass *S)
{
  if (i2m_refine_slivers_has_work(r) || (S->bound >= S->final_bound && S->caps)) return I2M_OK;
  double min_all;
  if (S->bound >= S->final_bound) i2m_refine_slivers_caps(r);
  S->bound = S->final_bound;
  S->stage_start = S->round;
  return S->watching ? list_from_watch(r, S) : collect_all(r, S->bound, &S->list, &min_all, NULL, NULL, NULL);
}

void i2m_refine_slivers_caps(i2m_refine_t *r) { r->slivers->caps = true; }

/* A new pass's state (bounds, one working set per worker) and its first count of the output
 * tets (this process's): the figures before it. */
static i2m_err_t pass_new(i2m_refine_t *r, double bound)
{
  pieces_invalidate(r); /* (the pass changes the mesh) */
  r->sliver_pass_ran = true;
  I2M_CALL(i2m_calloc(1, sizeof *r->slivers, &r->slivers));
  struct sliver_pass *S = r->slivers;
  S->final_bound = bound;
  S->cos_final = cos(bound * (I2M_PI / 180.0));
  S->cap_shift = S->cos_final + cos(widest_allowed(bound) * (I2M_PI / 180.0));
  S->bound = bound < FIRST_STAGE ? bound : FIRST_STAGE;
  S->watching = !dist_tracking(r); /* (under MPI a task lists its tile's slivers itself) */
  S->cos_watch = cos((bound + WATCH_MARGIN) * (I2M_PI / 180.0));
  S->t0 = i2m_wtime();
  i2m_err_t err = i2m_calloc((size_t)r->nworkers, sizeof *S->per, &S->per);
  for (int k = 0; err == I2M_OK && k < r->nworkers; k++) S->per[k].w = &r->workers[k];
  if (err == I2M_OK)
    err = collect_all(r, bound, &S->list, &S->st.min_before, &S->st.slivers_before, S->watching ? &S->watch : NULL,
                      &S->st.bands_before);
  if (err != I2M_OK) pass_free(r);
  return err;
}

i2m_err_t i2m_refine_slivers_begin(i2m_refine_t *r, double bound)
{
  I2M_CHECK(!r->slivers, I2M_ERR_INTERNAL, "a sliver pass is already under way");
  I2M_CALL(refine_sort_tets(r)); /* (its cost is won back in the pass, then in extraction: 1.4 -> 0.8 s on the liver) */
  I2M_CALL(pass_new(r, bound));
  struct sliver_pass *S = r->slivers;
  while (S->list.n > 0 && !(S->list.a[S->list.n - 1].angle < S->bound)) /* the first stage's (sorted) */
    S->list.n--;
  i2m_err_t err = next_stage_if_done(r, S);
  if (err == I2M_OK) err = i2m_refine_tiling_begin(r); /* (the workers stop taking locks) */
  if (err == I2M_OK) S->seq_gid = tiles_spare_gid(r->tiling);
  if (err == I2M_OK) err = i2m_malloc(r->tiling->ntiles + 1, sizeof *S->first, &S->first);
  if (err == I2M_OK) err = i2m_malloc(r->tiling->ntiles, sizeof *S->active, &S->active);
  if (err != I2M_OK) {
    i2m_refine_tiling_end(r);
    pass_free(r);
    return err;
  }
  i2m_progress_begin(&S->progress, "sliver perturbation", "vertex moves");
  return I2M_OK;
}

/* Rounds go on while slivers are left and the last round kept a move; after a round that
 * kept none, one wide round (more targets, farther, and vertices left out: drop_first) before
 * the stage ends: the liver at 6 M tets kept 7 tets below 5 degrees after a round kept
 * nothing, and one of them (1.7 degrees) to the end of the pass. */
bool i2m_refine_slivers_has_work(const i2m_refine_t *r)
{
  const struct sliver_pass *S = r->slivers;
  int64_t tried, kept;
  moves_so_far(r, S, &tried, &kept);
  const bool stalled = S->round > S->stage_start && kept == S->kept_before_round;
  return S->list.n > 0 && S->round - S->stage_start < ROUNDS && !(stalled && S->wide);
}

/* The round's slivers grouped by tile (a stable counting sort: each tile's stay in order). */
static i2m_err_t group_by_tile(i2m_refine_t *r, struct sliver_pass *S)
{
  const uint32_t nt = r->tiling->ntiles;
  I2M_CALL(i2m_realloc(S->list.n ? S->list.n : 1, sizeof *S->by_tile, &S->by_tile));
  memset(S->first, 0, (nt + 1) * sizeof *S->first);
  for (size_t k = 0; k < S->list.n; k++) S->first[tiles_tile_of_tet(r, S->list.a[k].t) + 1]++;
  for (uint32_t id = 0; id < nt; id++) S->first[id + 1] += S->first[id];
  for (size_t k = 0; k < S->list.n; k++) { /* (first[id] runs ahead while filling; reset below) */
    const uint32_t id = tiles_tile_of_tet(r, S->list.a[k].t);
    S->by_tile[S->first[id]++] = S->list.a[k];
  }
  for (uint32_t id = nt; id > 0; id--) S->first[id] = S->first[id - 1];
  S->first[0] = 0;
  return I2M_OK;
}

i2m_err_t i2m_refine_slivers_phase(i2m_refine_t *r, int color, const uint32_t **tiles, uint32_t *ntiles)
{
  struct sliver_pass *S = r->slivers;
  tiling_t *g = r->tiling;
  if (color == 0) {
    int64_t tried, kept;
    moves_so_far(r, S, &tried, &kept);
    S->wide = S->round > S->stage_start && kept == S->kept_before_round;
    S->kept_before_round = kept;
    i2m_debug("slivers: round %d, below %g deg: %zu slivers; %lld moves tried, %lld kept so far, %.2f s", S->round, S->bound,
              S->list.n, (long long)tried, (long long)S->kept_before_round, i2m_wtime() - S->t0);
    I2M_CALL(group_by_tile(r, S));
  }
  S->nactive = 0;
  for (uint32_t id = 0; id < g->ntiles; id++)
    if (tiles_color(g, id) == color && S->first[id + 1] > S->first[id]) S->active[S->nactive++] = id;
  for (uint32_t i = 0; i < S->nactive; i++) { /* a move needs a few tets more than it frees at most */
    const uint32_t id = S->active[i], n = S->first[id + 1] - S->first[id];
    I2M_CALL(i2m_dt_slots_grant(r->dt, &g->tile[id].slots, 256 + 64 * n, 16 + 2 * n));
  }
  I2M_CALL(vgrid_reserve(&r->surf, r->dt->cap_v)); /* nobody grows the grids while tiles run */
  I2M_CALL(vgrid_reserve(&r->freev, r->dt->cap_v));
  *tiles = S->active;
  *ntiles = S->nactive;
  return I2M_OK;
}

/* Treats slivers [0, n) of s with P; the deferred ones go to P's list. */
static i2m_err_t treat_all(perturb_t *P, const sliver_t *s, size_t n)
{
  for (size_t k = 0; k < n; k++) {
    sliver_t cur = s[k];
    const int got = treat_sliver(P, &cur);
    I2M_CHECK(got != MOVE_ERROR, I2M_ERR_INTERNAL, "sliver perturbation: a vertex could not be moved back (%s)",
              i2m_error_message());
    if (got == MOVE_DEFERRED) I2M_CALL(list_push(&P->deferred, &cur));
  }
  return I2M_OK;
}

static i2m_err_t tile_slivers_dist(i2m_refine_t *r, int k, uint32_t id);

i2m_err_t i2m_refine_tile_slivers(i2m_refine_t *r, int k, uint32_t id)
{
  if (dist_tracking(r)) return tile_slivers_dist(r, k, id);
  struct sliver_pass *S = r->slivers;
  perturb_t *P = &S->per[k];
  P->rng = rng_seed(r, S->round, id);
  tiles_bind(P->w, id, false);
  i2m_err_t err = treat_all(P, S->by_tile + S->first[id], S->first[id + 1] - S->first[id]);
  tiles_unbind(P->w);
  return err;
}

i2m_err_t i2m_refine_slivers_merge(i2m_refine_t *r)
{
  struct sliver_pass *S = r->slivers;
  for (uint32_t i = 0; i < S->nactive; i++) i2m_dt_slots_release(r->dt, &r->tiling->tile[S->active[i]].slots);
  int64_t tried, kept;
  moves_so_far(r, S, &tried, &kept);
  i2m_progress_update(&S->progress, tried);
  return I2M_OK;
}

i2m_err_t i2m_refine_slivers_sequential(i2m_refine_t *r)
{
  struct sliver_pass *S = r->slivers;
  perturb_t *P0 = &S->per[0];
  for (int k = 1; k < r->nworkers; k++) { /* every thread's deferred slivers, in order */
    const sliver_list_t *D = &S->per[k].deferred;
    for (size_t i = 0; i < D->n; i++) I2M_CALL(list_push(&P0->deferred, &D->a[i]));
    S->per[k].deferred.n = 0;
  }
  sliver_list_t todo = P0->deferred;
  P0->deferred = (sliver_list_t){0};
  if (todo.n > 1) qsort(todo.a, todo.n, sizeof *todo.a, cmp_sliver);
  P0->rng = rng_seed(r, S->round, TILE_NONE);
  i2m_err_t err = treat_all(P0, todo.a, todo.n);
  i2m_free(&todo.a);
  P0->deferred.n = 0; /* (no zone here: only a target beyond the walk's reach defers; dropped) */
  if (err == I2M_OK) err = collect_after_round(r, S);
  S->round++;
  if (err == I2M_OK) err = next_stage_if_done(r, S);
  return err;
}

/* The pass's closing figures: its moves, the slivers left below `bound`, its time. */
static i2m_err_t final_stats(i2m_refine_t *r, struct sliver_pass *S, double bound)
{
  moves_so_far(r, S, &S->st.tried, &S->st.kept);
  int64_t in_place = 0, in_place_kept = 0, cut = 0, prejudged = 0;
  S->st.inserted = S->st.removed = 0;
  for (int k = 0; k < r->nworkers; k++) {
    const perturb_t *P = &S->per[k];
    S->st.inserted += P->inserted, S->st.removed += P->dropped;
    in_place += P->in_place, in_place_kept += P->in_place_kept, cut += P->cut, prejudged += P->prejudged;
  }
  i2m_err_t err = I2M_OK;
  if (!(S->watching && figures_from_watch(r, bound, &S->st.min_after, &S->st.slivers_after)))
    err = collect_all(r, bound, &S->list, &S->st.min_after, &S->st.slivers_after, NULL, NULL);
  S->st.seconds = i2m_wtime() - S->t0;
  i2m_debug("slivers: %lld moves tried, %lld kept; in place (without a removal) %lld tried, %lld kept; %lld refused as "
            "they would cut a tissue's path, %lld by a rule before their insertion; %.2f s",
            (long long)S->st.tried, (long long)S->st.kept, (long long)in_place, (long long)in_place_kept, (long long)cut,
            (long long)prejudged, S->st.seconds);
  return err;
}

i2m_err_t i2m_refine_slivers_end(i2m_refine_t *r, i2m_sliver_stats_t *st)
{
  struct sliver_pass *S = r->slivers;
  i2m_err_t err = I2M_OK;
  if (S) {
    err = final_stats(r, S, S->bound);
    i2m_progress_end(&S->progress, S->st.tried);
    if (st) *st = S->st;
  }
  i2m_refine_tiling_end(r);
  pass_free(r);
  return err;
}

i2m_err_t i2m_refine_perturb_slivers(i2m_refine_t *r, double bound, i2m_sliver_stats_t *st)
{
  I2M_CALL(i2m_refine_slivers_begin(r, bound));
  i2m_err_t err = I2M_OK;
  while (err == I2M_OK && i2m_refine_slivers_has_work(r)) {
    for (int color = 0; color < i2m_refine_tiling_colors(r) && err == I2M_OK; color++) {
      const uint32_t *tiles;
      uint32_t n;
      err = i2m_refine_slivers_phase(r, color, &tiles, &n);
      for (uint32_t i = 0; i < n && err == I2M_OK; i++) err = i2m_refine_tile_slivers(r, 0, tiles[i]);
      if (err == I2M_OK) err = i2m_refine_slivers_merge(r);
    }
    if (err == I2M_OK) err = i2m_refine_slivers_sequential(r);
  }
  const i2m_err_t end = i2m_refine_slivers_end(r, st);
  return err != I2M_OK ? err : end;
}

/* ---- under the dist layer: the octree's tiles; a task finds its tile's slivers itself (the
 * tile's submesh may have come from another rank since the round began), treats them inside
 * its zone, and what the zone cannot hold waits for the next round ---- */

i2m_err_t i2m_refine_slivers_dist_begin(i2m_refine_t *r, double bound)
{
  I2M_CHECK(!r->slivers && r->tiling && r->tiling->octree && dist_tracking(r), I2M_ERR_INTERNAL,
            "the distributed sliver pass needs the octree's tiles");
  I2M_CALL(pass_new(r, bound)); /* (this rank's figures before) */
  struct sliver_pass *S = r->slivers;
  S->list.n = 0; /* (each task lists its tile's slivers) */
  S->ncache = r->tiling->ntiles;
  S->cache_bound = -1.0; /* (no stage yet) */
  i2m_err_t err = i2m_calloc(S->ncache, sizeof *S->cache, &S->cache);
  if (err == I2M_OK) err = i2m_calloc(S->ncache, sizeof *S->cache_ok, &S->cache_ok);
  if (err != I2M_OK) pass_free(r);
  return err;
}

/* The tiles' lists are of the stage under way (a new stage: none known), and none that a task
 * made tets in beyond its block is. */
static void caches_now(i2m_refine_t *r)
{
  struct sliver_pass *S = r->slivers;
  if (S->cache_bound != S->bound || S->cache_caps != S->caps) {
    memset(S->cache_ok, 0, S->ncache);
    S->cache_bound = S->bound;
    S->cache_caps = S->caps;
  }
  for (int k = 0; k < r->nworkers; k++) {
    perturb_t *P = &S->per[k];
    for (uint32_t i = 0; i < P->nstale; i++) S->cache_ok[P->stale[i]] = 0;
    P->nstale = 0;
  }
}

void slivers_forget_tile(i2m_refine_t *r, uint32_t id)
{
  if (r->slivers && r->slivers->cache_ok) r->slivers->cache_ok[id] = 0;
}

void i2m_refine_slivers_dist_round(i2m_refine_t *r, double bound, int round, bool wide)
{
  r->slivers->bound = bound;
  r->slivers->round = round;
  r->slivers->wide = wide;
}

/* Tile id's slivers now, in order. */
static i2m_err_t tile_slivers(const i2m_refine_t *r, uint32_t id, sliver_list_t *L)
{
  const i2m_dt_t *dt = r->dt;
  const tile_t *tl = &r->tiling->tile[id];
  const double cos_bound = cos(r->slivers->bound * (I2M_PI / 180.0));
  L->n = 0;
  for (uint32_t i = 0; i < tl->ntets; i++) { /* (stale entries: their meta moved on) */
    const uint32_t t = tl->tets[i].t;
    if (i2m_dt_stamp(dt, t) != tl->tets[i].meta || !tet_kept(dt, t)) continue;
    I2M_CALL(consider(dt, t, tet_badness(r, t, NULL), cos_bound, L));
  }
  if (L->n > 1) qsort(L->a, L->n, sizeof *L->a, cmp_sliver);
  size_t n = 0; /* (a tet filed twice is listed twice) */
  for (size_t k = 0; k < L->n; k++)
    if (n == 0 || L->a[k].t != L->a[n - 1].t || L->a[k].meta != L->a[n - 1].meta) L->a[n++] = L->a[k];
  L->n = n;
  return I2M_OK;
}

/* Tile id's list, made if it is not known (the master thread, no job running). */
static i2m_err_t tile_cache(i2m_refine_t *r, uint32_t id, const sliver_list_t **out)
{
  struct sliver_pass *S = r->slivers;
  caches_now(r);
  if (!S->cache_ok[id]) {
    I2M_CALL(tile_slivers(r, id, &S->cache[id]));
    S->cache_ok[id] = 1;
  }
  *out = &S->cache[id];
  return I2M_OK;
}

int64_t i2m_refine_tile_sliver_count(i2m_refine_t *r, uint32_t id)
{
  const sliver_list_t *L;
  return tile_cache(r, id, &L) == I2M_OK ? (int64_t)L->n : 0;
}

i2m_err_t i2m_refine_slivers_dist_prepare(i2m_refine_t *r, const uint32_t *tiles, uint32_t n)
{
  tiling_t *g = r->tiling;
  pieces_invalidate(r); /* (the moves change the mesh) */
  g->nactive = 0;
  for (uint32_t i = 0; i < n; i++) {
    const sliver_list_t *L;
    I2M_CALL(tile_cache(r, tiles[i], &L));
    const int64_t m = (int64_t)L->n;
    I2M_CALL(i2m_dt_slots_grant(r->dt, &g->tile[tiles[i]].slots, (uint32_t)(256 + 64 * m), (uint32_t)(16 + 2 * m)));
    g->active[g->nactive++] = tiles[i];
  }
  I2M_CALL(vgrid_reserve(&r->surf, r->dt->cap_v)); /* nobody grows the grids while tiles run */
  return vgrid_reserve(&r->freev, r->dt->cap_v);
}

/* The slivers among the live output tets that this task made (not filed in their tiles' lists
 * yet) whose centroids lie in its zone, in its tile or a neighbour's, in order: the task's
 * next round.  (Only those of its own tile: the liver at 2 ranks left 939-988 slivers to the
 * next global round, 185-195 tasks; with the zone's, 332-351 and 126-145.  Its first list's
 * slivers left tried again too: no more moves kept, in the task or in the next round.) */
static i2m_err_t born_slivers(const i2m_refine_t *r, const perturb_t *P, uint32_t born0, sliver_list_t *L)
{
  const i2m_dt_t *dt = r->dt;
  const i2m_refine_worker_t *w = P->w;
  const double cos_bound = cos(r->slivers->bound * (I2M_PI / 180.0));
  L->n = 0;
  for (uint32_t i = born0; i < w->nborn; i++) { /* (from this task's first: a job may hold two) */
    const uint32_t t = w->born[i].t;
    if (i2m_dt_stamp(dt, t) != w->born[i].meta || !tet_kept(dt, t)) continue;
    double c[3];
    i2m_dt_centroid(dt, t, c);
    if (!tiles_zone_holds(w, c)) continue;
    I2M_CALL(consider(dt, t, tet_badness(r, t, NULL), cos_bound, L));
  }
  if (L->n > 1) qsort(L->a, L->n, sizeof *L->a, cmp_sliver);
  return I2M_OK;
}

/* After a task that kept changes (its block still bound): each of its block's known lists
 * keeps its entries still alive and gains the slivers among the output tets the task made
 * there, in order: the same list a look at the tile's tets would make.  A move in place keeps
 * its tets' slots but not their angles: after one, the block's lists are not known. */
static i2m_err_t update_caches(i2m_refine_t *r, perturb_t *P, uint32_t born0, bool moved_in_place)
{
  struct sliver_pass *S = r->slivers;
  const i2m_dt_t *dt = r->dt;
  const i2m_refine_worker_t *w = P->w;
  uint32_t ids[125];
  const uint32_t nb = tiles_of_block(r->tiling, w->ctx.block, ids);
  if (moved_in_place)
    for (uint32_t i = 0; i < nb; i++) S->cache_ok[ids[i]] = 0;
  for (uint32_t i = 0; i < nb; i++) {
    if (!S->cache_ok[ids[i]]) continue;
    sliver_list_t *L = &S->cache[ids[i]];
    size_t n = 0;
    for (size_t j = 0; j < L->n; j++)
      if (i2m_dt_stamp(dt, L->a[j].t) == L->a[j].meta) L->a[n++] = L->a[j];
    L->n = n;
  }
  const double cos_bound = cos(S->bound * (I2M_PI / 180.0));
  for (uint32_t i = born0; i < w->nborn; i++) {
    const uint32_t t = w->born[i].t;
    if (i2m_dt_stamp(dt, t) != w->born[i].meta || !tet_kept(dt, t)) continue;
    const uint32_t id = tiles_tile_of_tet(r, t);
    bool inside = false;
    for (uint32_t j = 0; j < nb && !inside; j++) inside = ids[j] == id;
    if (!inside) { /* (beyond the block: known again only after the job, see caches_now) */
      I2M_CALL(grow_list(&P->stale, &P->cap_stale, P->nstale + 1));
      P->stale[P->nstale++] = id;
      continue;
    }
    if (S->cache_ok[id]) I2M_CALL(consider(dt, t, tet_badness(r, t, NULL), cos_bound, &S->cache[id]));
  }
  for (uint32_t i = 0; i < nb; i++) {
    sliver_list_t *L = &S->cache[ids[i]];
    if (S->cache_ok[ids[i]] && L->n > 1) qsort(L->a, L->n, sizeof *L->a, cmp_sliver);
  }
  return I2M_OK;
}

/* Worker k on tile id's slivers (dist): up to TASK_ROUNDS rounds, the later ones over the
 * slivers among the tets the task made in its zone.  Each global round moves blocks between
 * the ranks, and the slivers a round's changes make are mostly next to them: without the
 * task's own rounds, the liver at 2 ranks took 17 global rounds (the pass 3.5 times its
 * one-process time). */
static i2m_err_t tile_slivers_dist(i2m_refine_t *r, int k, uint32_t id)
{
  struct sliver_pass *S = r->slivers;
  perturb_t *P = &S->per[k];
  I2M_CHECK(S->cache_ok[id], I2M_ERR_INTERNAL, "tile %u's slivers were not listed before its task", id);
  const sliver_list_t *L = &S->cache[id];
  const int64_t changes0 = P->kept + P->inserted, in_place0 = P->in_place_kept;
  const uint32_t born0 = P->w->nborn;
  P->rng = rng_seed(r, S->round, id);
  tiles_bind(P->w, id, false);
  i2m_err_t err = treat_all(P, L->a, L->n);
  for (int inner = 1; err == I2M_OK && inner < TASK_ROUNDS; inner++) {
    err = born_slivers(r, P, born0, &P->inner);
    if (err != I2M_OK || P->inner.n == 0) break;
    err = treat_all(P, P->inner.a, P->inner.n);
  }
  if (err == I2M_OK && P->kept + P->inserted != changes0) /* (else every trial was undone: the same tets) */
    err = update_caches(r, P, born0, P->in_place_kept != in_place0);
  tiles_unbind(P->w);
  P->deferred.n = 0; /* (the next round's task finds them again, maybe with its zone placed better) */
  P->ntouched = 0;
  return err;
}

void i2m_refine_slivers_dist_moves(const i2m_refine_t *r, int64_t *tried, int64_t *kept)
{
  moves_so_far(r, r->slivers, tried, kept);
}

i2m_err_t i2m_refine_slivers_dist_end(i2m_refine_t *r, i2m_sliver_stats_t *st)
{
  struct sliver_pass *S = r->slivers;
  i2m_err_t err = I2M_OK;
  if (S) {
    err = final_stats(r, S, S->final_bound);
    if (st) *st = S->st;
  }
  pass_free(r);
  return err;
}
