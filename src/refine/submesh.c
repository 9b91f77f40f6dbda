/* Refine layer: the submeshes that the dist layer moves between ranks (a tile of the octree,
 * its tets, their vertices, its bad elements and its state), as flat byte buffers with 64-bit
 * global vertex ids.
 *
 * A rank holds some tiles; its triangulation holds their tets and the vertices they use.  A
 * face whose other side is not held is I2M_DT_REMOTE (its tet is frozen: a cavity that reaches
 * it gives I2M_DT_FROZEN) and is filed in the remote-face map under the sorted global ids of
 * its vertices, with the cell of the tet across it.  A submesh that arrives is joined to the
 * local tets by matching its outer faces in that map (adjacency rebuilt on global ids, never on
 * coordinates); one that leaves takes its tets and every vertex no local tet uses any more.
 * Which vertices those are is known without a pass over the mesh: a local vertex that some
 * tet elsewhere also uses is a vertex of a remote face of a local tet (its star is face-
 * connected, so the local part of it is bounded by faces to tets not held), so a vertex of
 * the leaving tets is kept exactly when it lies on a remote face after they left (the count
 * vremote).  The id map (global id -> slot) holds every local vertex.
 *
 * All of this runs on the thread that talks MPI while no task runs (quiescent), except
 * i2m_refine_pack, which reads only the tile's own tets and vertices: no task changes them
 * (a task changes only tets of its block, and never borders a tile outside it). */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

#define PACK_MAGIC 0x69326d53u /* "i2mS" */
#define PACK_EXTERNAL 0x80000000u /* a tet's neighbour word: external face k (| k) */
#define PACK_NONE 0xFFFFFFFFu     /* a tet's neighbour word: the box hull; a pending removal's vertex: none */

/* ---- maps (open addressing, linear probing, deletion by backward shift) ---- */

typedef struct {
  i2m_gidx_t gid; /* -1: empty */
  uint32_t v;
} gid_slot_t;

typedef struct {
  i2m_gidx_t key[3]; /* the face's sorted global ids; key[0] = -1: empty */
  uint32_t face;     /* 4t + i of the local tet */
  int32_t cell;      /* the cell of the tet across it */
  uint16_t ghost;    /* the label index of the tet across it (i2m_refine_dist_ghosts) */
} rface_t;

struct submesh {
  uint16_t *vremote; /* [cap_v] remote faces of local tets that hold each vertex */
  uint32_t cap_v;
  gid_slot_t *ids;   /* global id -> vertex slot */
  size_t cap_ids, nids;
  rface_t *rf;       /* remote faces */
  size_t cap_rf, nrf;
  uint32_t *tmark;   /* [cap_t] scratch: a tet's index in the submesh being packed or dropped (PACK_NONE) */
  uint32_t cap_tmark;
  uint32_t *vmark;   /* [cap_v] scratch: a vertex's index in it (PACK_NONE) */
  uint32_t cap_vmark;
  int32_t *location; /* [ntiles] the rank that holds each tile, as the dist layer last said */
};

static uint64_t mix(uint64_t z)
{
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

static size_t id_home(const struct submesh *S, i2m_gidx_t g) { return (size_t)mix((uint64_t)g) & (S->cap_ids - 1); }

static uint32_t id_find(const struct submesh *S, i2m_gidx_t g)
{
  for (size_t h = id_home(S, g);; h = (h + 1) & (S->cap_ids - 1)) {
    if (S->ids[h].gid == g) return S->ids[h].v;
    if (S->ids[h].gid < 0) return PACK_NONE;
  }
}

static i2m_err_t id_rehash(struct submesh *S, size_t cap)
{
  gid_slot_t *old = S->ids;
  const size_t ocap = S->cap_ids;
  I2M_CALL(i2m_malloc(cap, sizeof *S->ids, &S->ids));
  for (size_t i = 0; i < cap; i++) S->ids[i].gid = -1;
  S->cap_ids = cap;
  for (size_t i = 0; i < ocap; i++) {
    if (old[i].gid < 0) continue;
    size_t h = id_home(S, old[i].gid);
    while (S->ids[h].gid >= 0) h = (h + 1) & (cap - 1);
    S->ids[h] = old[i];
  }
  i2m_free(&old);
  return I2M_OK;
}

/* Files (or refiles) global id g at slot v. */
static i2m_err_t id_put(struct submesh *S, i2m_gidx_t g, uint32_t v)
{
  if (2 * (S->nids + 1) > S->cap_ids) I2M_CALL(id_rehash(S, S->cap_ids ? 2 * S->cap_ids : 4096));
  size_t h = id_home(S, g);
  while (S->ids[h].gid >= 0 && S->ids[h].gid != g) h = (h + 1) & (S->cap_ids - 1);
  if (S->ids[h].gid < 0) S->nids++;
  S->ids[h] = (gid_slot_t){g, v};
  return I2M_OK;
}

static void id_del(struct submesh *S, i2m_gidx_t g)
{
  const size_t mask = S->cap_ids - 1;
  size_t h = id_home(S, g);
  while (S->ids[h].gid != g) {
    if (S->ids[h].gid < 0) return;
    h = (h + 1) & mask;
  }
  for (size_t j = (h + 1) & mask;; j = (j + 1) & mask) { /* backward shift */
    if (S->ids[j].gid < 0) break;
    const size_t home = id_home(S, S->ids[j].gid);
    if (((j - home) & mask) >= ((j - h) & mask)) {
      S->ids[h] = S->ids[j];
      h = j;
    }
  }
  S->ids[h].gid = -1;
  S->nids--;
}

static size_t rf_home(const struct submesh *S, const i2m_gidx_t k[3])
{
  return (size_t)mix((uint64_t)k[0] * 0x9E3779B97F4A7C15ull ^ mix((uint64_t)k[1]) ^ mix((uint64_t)k[2] + 0x1234567ull)) &
         (S->cap_rf - 1);
}

static bool key_eq(const i2m_gidx_t a[3], const i2m_gidx_t b[3]) { return a[0] == b[0] && a[1] == b[1] && a[2] == b[2]; }

static rface_t *rf_find(const struct submesh *S, const i2m_gidx_t k[3])
{
  if (!S->cap_rf) return NULL;
  for (size_t h = rf_home(S, k);; h = (h + 1) & (S->cap_rf - 1)) {
    if (S->rf[h].key[0] < 0) return NULL;
    if (key_eq(S->rf[h].key, k)) return &S->rf[h];
  }
}

static i2m_err_t rf_rehash(struct submesh *S, size_t cap)
{
  rface_t *old = S->rf;
  const size_t ocap = S->cap_rf;
  I2M_CALL(i2m_malloc(cap, sizeof *S->rf, &S->rf));
  for (size_t i = 0; i < cap; i++) S->rf[i].key[0] = -1;
  S->cap_rf = cap;
  for (size_t i = 0; i < ocap; i++) {
    if (old[i].key[0] < 0) continue;
    size_t h = rf_home(S, old[i].key);
    while (S->rf[h].key[0] >= 0) h = (h + 1) & (cap - 1);
    S->rf[h] = old[i];
  }
  i2m_free(&old);
  return I2M_OK;
}

static i2m_err_t rf_put(struct submesh *S, rface_t f)
{
  if (2 * (S->nrf + 1) > S->cap_rf) I2M_CALL(rf_rehash(S, S->cap_rf ? 2 * S->cap_rf : 4096));
  size_t h = rf_home(S, f.key);
  while (S->rf[h].key[0] >= 0) {
    I2M_CHECK(!key_eq(S->rf[h].key, f.key), I2M_ERR_INTERNAL, "a face is another rank's twice");
    h = (h + 1) & (S->cap_rf - 1);
  }
  S->rf[h] = f;
  S->nrf++;
  return I2M_OK;
}

static void rf_del(struct submesh *S, rface_t *f)
{
  const size_t mask = S->cap_rf - 1;
  size_t h = (size_t)(f - S->rf);
  for (size_t j = (h + 1) & mask;; j = (j + 1) & mask) {
    if (S->rf[j].key[0] < 0) break;
    const size_t home = rf_home(S, S->rf[j].key);
    if (((j - home) & mask) >= ((j - h) & mask)) {
      S->rf[h] = S->rf[j];
      h = j;
    }
  }
  S->rf[h].key[0] = -1;
  S->nrf--;
}

/* ---- geometry of faces and tiles ---- */

static const int FACE_V[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};

/* The sorted global ids of face i of tet t. */
static void face_key(const i2m_dt_t *dt, uint32_t t, int i, i2m_gidx_t k[3])
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (int j = 0; j < 3; j++) k[j] = i2m_dt_gid(dt, v[FACE_V[i][j]]);
  for (int a = 1; a < 3; a++)
    for (int b = a; b > 0 && k[b] < k[b - 1]; b--) {
      const i2m_gidx_t x = k[b];
      k[b] = k[b - 1];
      k[b - 1] = x;
    }
}

static void vremote_add(struct submesh *S, const i2m_dt_t *dt, uint32_t t, int i, int d)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (int j = 0; j < 3; j++) S->vremote[v[FACE_V[i][j]]] = (uint16_t)(S->vremote[v[FACE_V[i][j]]] + d);
}

/* Face i of local tet t becomes another rank's (the tet across lies in `cell`). */
static i2m_err_t make_remote(struct submesh *S, i2m_dt_t *dt, uint32_t t, int i, int32_t cell)
{
  rface_t f;
  face_key(dt, t, i, f.key);
  f.face = 4 * t + (uint32_t)i;
  f.cell = cell;
  f.ghost = 0;
  I2M_CALL(rf_put(S, f));
  dt->tn[4 * (size_t)t + i] = I2M_DT_REMOTE;
  vremote_add(S, dt, t, i, +1);
  return I2M_OK;
}

static int32_t tile_of(const i2m_refine_t *r, uint32_t t) { return (int32_t)tiles_tile_of_tet(r, t); }

/* ---- capacity of the per-slot arrays ---- */

static i2m_err_t grow_u32(uint32_t **a, uint32_t *cap, uint32_t need, uint32_t fill)
{
  if (need <= *cap) return I2M_OK;
  const uint32_t c = need + need / 2 + 1024;
  I2M_CALL(i2m_realloc(c, sizeof **a, a));
  for (uint32_t i = *cap; i < c; i++) (*a)[i] = fill;
  *cap = c;
  return I2M_OK;
}

static i2m_err_t sub_room(struct submesh *S, const i2m_dt_t *dt)
{
  if (dt->cap_v > S->cap_v) {
    I2M_CALL(i2m_realloc(dt->cap_v, sizeof *S->vremote, &S->vremote));
    memset(S->vremote + S->cap_v, 0, (dt->cap_v - S->cap_v) * sizeof *S->vremote);
    S->cap_v = dt->cap_v;
  }
  I2M_CALL(grow_u32(&S->tmark, &S->cap_tmark, dt->cap_t, PACK_NONE));
  return grow_u32(&S->vmark, &S->cap_vmark, dt->cap_v, PACK_NONE);
}

/* ---- the tiles' lists of tets ---- */

static i2m_err_t tile_file(tile_t *tl, uint32_t t, uint32_t meta)
{
  if (tl->ntets == tl->cap_tets) {
    const uint32_t c = tl->cap_tets ? 2 * tl->cap_tets : 256;
    I2M_CALL(i2m_realloc(c, sizeof *tl->tets, &tl->tets));
    tl->cap_tets = c;
  }
  tl->tets[tl->ntets++] = (tetref_t){t, meta};
  return I2M_OK;
}

/* Keeps the live entries of a tile's list (in order). */
static void tile_compact(const i2m_dt_t *dt, tile_t *tl)
{
  uint32_t n = 0;
  for (uint32_t i = 0; i < tl->ntets; i++)
    if (i2m_dt_stamp(dt, tl->tets[i].t) == tl->tets[i].meta) tl->tets[n++] = tl->tets[i];
  tl->ntets = tl->live_tets = n;
}

i2m_err_t dist_note_tets(i2m_refine_worker_t *w, const uint32_t *t, uint32_t n)
{
  if (w->nborn + n > w->cap_born) {
    const uint32_t c = w->nborn + n + (w->nborn + n) / 2 + 256;
    I2M_CALL(i2m_realloc(c, sizeof *w->born, &w->born));
    w->cap_born = c;
  }
  for (uint32_t k = 0; k < n; k++) w->born[w->nborn++] = (tetref_t){t[k], i2m_dt_stamp(w->r->dt, t[k])};
  return I2M_OK;
}

i2m_err_t dist_note_vertex(i2m_refine_worker_t *w, uint32_t v)
{
  if (w->nbornv == w->cap_bornv) {
    const uint32_t c = w->cap_bornv ? 2 * w->cap_bornv : 256;
    I2M_CALL(i2m_realloc(c, sizeof *w->bornv, &w->bornv));
    w->cap_bornv = c;
  }
  w->bornv[w->nbornv++] = v;
  return I2M_OK;
}

/* A list's tets lie anywhere in the arrays, and every load waits for memory: entry i's loop
 * requests the words of the tet PREFETCH_AHEAD entries on (its stamp, vertices, mark), and
 * the marks of the vertices of the live one half as far (whose words have arrived by then).
 * Forced inline: GCC drops a call to a function that only prefetches under a condition. */
#define PREFETCH_AHEAD 16
static I2M_INLINE void prefetch_tet(const i2m_dt_t *dt, uint32_t t)
{
  I2M_PREFETCH(dt->tv + 4 * (size_t)t);
  I2M_PREFETCH(&dt->meta[t]);
}

static I2M_INLINE void prefetch_listed(const struct submesh *S, const i2m_dt_t *dt, const tetref_t *list, uint32_t n,
                                       uint32_t i)
{
  if (i + PREFETCH_AHEAD < n) {
    prefetch_tet(dt, list[i + PREFETCH_AHEAD].t);
    I2M_PREFETCH(&S->tmark[list[i + PREFETCH_AHEAD].t]);
  }
  if (i + PREFETCH_AHEAD / 2 < n) { /* (a stale entry's slot may be a running task's: not read) */
    const tetref_t e = list[i + PREFETCH_AHEAD / 2];
    if (i2m_dt_stamp(dt, e.t) != e.meta) return;
    const uint32_t *v = dt->tv + 4 * (size_t)e.t;
    for (int j = 0; j < 4; j++) I2M_PREFETCH(&S->vmark[v[j]]);
  }
}

/* As prefetch_listed, for what filing a new tet reads: its stamp, and its vertices'
 * coordinates (its cell is its centroid's). */
static I2M_INLINE void prefetch_born(const i2m_dt_t *dt, const tetref_t *list, uint32_t n, uint32_t i)
{
  if (i + PREFETCH_AHEAD < n) prefetch_tet(dt, list[i + PREFETCH_AHEAD].t);
  if (i + PREFETCH_AHEAD / 2 < n) { /* (only a live one's: the others are skipped) */
    const tetref_t e = list[i + PREFETCH_AHEAD / 2];
    if (i2m_dt_stamp(dt, e.t) != e.meta) return;
    const uint32_t *v = dt->tv + 4 * (size_t)e.t;
    for (int j = 0; j < 4; j++) I2M_PREFETCH(i2m_dt_xyz(dt, v[j]));
  }
}

i2m_err_t i2m_refine_dist_merge(i2m_refine_t *r)
{
  struct submesh *S = r->sub;
  i2m_dt_t *dt = r->dt;
  tiling_t *g = r->tiling;
  I2M_CALL(sub_room(S, dt));
  for (int k = 0; k < r->nworkers; k++) {
    i2m_refine_worker_t *w = &r->workers[k];
    for (uint32_t i = 0; i < w->nborn; i++) {
      prefetch_born(dt, w->born, w->nborn, i);
      const tetref_t e = w->born[i];
      if (i2m_dt_stamp(dt, e.t) != e.meta) continue; /* (most die within the task) */
      tile_t *tl = &g->tile[tiles_tile_of_tet(r, e.t)];
      I2M_CALL(tile_file(tl, e.t, e.meta));
      if (tl->ntets > 2 * tl->live_tets + 1024) tile_compact(dt, tl);
    }
    for (uint32_t i = 0; i < w->nbornv; i++) {
      const uint32_t v = w->bornv[i];
      if (dt->vkind[v] != I2M_VK_DEAD) I2M_CALL(id_put(S, i2m_dt_gid(dt, v), v));
    }
    w->nborn = w->nbornv = 0;
  }
  return I2M_OK;
}

/* ---- begin and end ---- */

static void sub_free(struct submesh **Sp)
{
  struct submesh *S = *Sp;
  if (!S) return;
  i2m_free(&S->vremote);
  i2m_free(&S->ids);
  i2m_free(&S->rf);
  i2m_free(&S->tmark);
  i2m_free(&S->vmark);
  i2m_free(&S->location);
  i2m_free(Sp);
}

i2m_err_t i2m_refine_dist_begin(i2m_refine_t *r, bool hold_all)
{
  I2M_CHECK(r->tiling && r->tiling->octree && !r->sub, I2M_ERR_INTERNAL, "the dist layer needs the octree's tiles");
  I2M_CALL(i2m_calloc(1, sizeof *r->sub, &r->sub));
  struct submesh *S = r->sub;
  i2m_dt_t *dt = r->dt;
  i2m_err_t err = sub_room(S, dt);
  if (err == I2M_OK) err = id_rehash(S, 4096);
  if (err == I2M_OK) err = rf_rehash(S, 4096);
  const uint32_t nv = i2m_dt_nverts_slots(dt), nt = i2m_dt_ntets_slots(dt);
  for (uint32_t v = 0; v < nv && err == I2M_OK; v++) /* (the box corners on every rank: ids 0..7) */
    if (dt->vkind[v] != I2M_VK_DEAD) err = id_put(S, i2m_dt_gid(dt, v), v);
  for (uint32_t id = 0; id < r->tiling->ntiles; id++) r->tiling->tile[id].held = hold_all;
  for (uint32_t t = 0; t < nt && err == I2M_OK; t++) { /* holding none: the virtual box's tets go */
    if (!i2m_dt_alive(dt, t)) continue;
    err = hold_all ? tile_file(&r->tiling->tile[tiles_tile_of_tet(r, t)], t, i2m_dt_stamp(dt, t)) : i2m_dt_give_tet(dt, t);
  }
  for (uint32_t id = 0; id < r->tiling->ntiles; id++) r->tiling->tile[id].live_tets = r->tiling->tile[id].ntets;
  if (err != I2M_OK) sub_free(&r->sub);
  return err;
}

void i2m_refine_dist_asynchronous(i2m_refine_t *r, bool on) { r->async_tasks = on; }

void i2m_refine_dist_end(i2m_refine_t *r)
{
  sub_free(&r->sub);
  for (int k = 0; k < r->nworkers; k++) r->workers[k].nborn = r->workers[k].nbornv = 0;
}

bool i2m_refine_holds(const i2m_refine_t *r, uint32_t id) { return r->tiling->tile[id].held; }

i2m_err_t i2m_refine_dist_set_location(i2m_refine_t *r, const int32_t *holder)
{
  struct submesh *S = r->sub;
  const uint32_t n = r->tiling->ntiles;
  if (!S->location) I2M_CALL(i2m_malloc(n, sizeof *S->location, &S->location));
  memcpy(S->location, holder, n * sizeof *holder);
  return I2M_OK;
}

const int32_t *i2m_refine_dist_location(const i2m_refine_t *r) { return r->sub ? r->sub->location : NULL; }

/* ---- the submesh buffer ---- */

typedef struct {
  uint32_t magic, tile, ntets, nverts, next, nq[NLEVELS], nwq[NLEVELS], npend, nwpend, grant, npts, nwpts, dirty;
  i2m_gidx_t gid_next;
  uint64_t seq;
} pack_header_t;

typedef struct {
  i2m_gidx_t gid;
  double x[3];
  uint32_t tag; /* a surface vertex's patch */
  uint8_t kind, near;  /* near: one of R7's candidates (a free vertex within 2 delta of an interface) */
  uint8_t pad[2];
} pack_vertex_t;

typedef struct {
  uint32_t v[4];  /* vertex indices in the buffer */
  uint32_t nb[4]; /* tet index in the buffer, PACK_EXTERNAL | k, or PACK_NONE (the box hull) */
  uint16_t label, pad;
} pack_tet_t;

typedef struct {
  i2m_gidx_t gid;
} pack_pend_t;

/* A growable byte buffer. */
typedef struct {
  unsigned char *b;
  size_t n, cap;
  bool failed;
} bytes_t;

static void *bytes_room(bytes_t *B, size_t k)
{
  if (B->failed) return NULL;
  if (B->n + k > B->cap) {
    size_t c = B->cap ? 2 * B->cap : 65536;
    while (c < B->n + k) c *= 2;
    if (i2m_realloc(c, 1, &B->b) != I2M_OK) {
      B->failed = true;
      return NULL;
    }
    B->cap = c;
  }
  void *p = B->b + B->n;
  B->n += k;
  return p;
}

static void bytes_put(bytes_t *B, const void *x, size_t k)
{
  if (k == 0) return; /* (x may be NULL then) */
  void *p = bytes_room(B, k);
  if (p) memcpy(p, x, k);
}

static bool is_near(const i2m_refine_t *r, uint32_t v) { return v < r->freev.cap_next && r->freev.tag[v] == VGRID_MEMBER; }

/* The tile's live tets, numbered in list order in tmark; their vertices in first-use order in
 * vmark (verts[] lists them).  Returns the counts. */
static i2m_err_t number_submesh(const i2m_refine_t *r, const tile_t *tl, uint32_t **tets, uint32_t *ntets,
                                uint32_t **verts, uint32_t *nverts)
{
  struct submesh *S = r->sub;
  const i2m_dt_t *dt = r->dt;
  uint32_t nt = 0, nv = 0;
  I2M_CALL(i2m_malloc(tl->ntets ? tl->ntets : 1, sizeof **tets, tets));
  I2M_CALL(i2m_malloc(4 * (size_t)tl->ntets + 1, sizeof **verts, verts));
  for (uint32_t i = 0; i < tl->ntets; i++) {
    prefetch_listed(S, dt, tl->tets, tl->ntets, i);
    const tetref_t e = tl->tets[i];
    if (i2m_dt_stamp(dt, e.t) != e.meta || S->tmark[e.t] != PACK_NONE) continue;
    S->tmark[e.t] = nt;
    (*tets)[nt++] = e.t;
    const uint32_t *v = dt->tv + 4 * (size_t)e.t;
    for (int j = 0; j < 4; j++)
      if (S->vmark[v[j]] == PACK_NONE) {
        S->vmark[v[j]] = nv;
        (*verts)[nv++] = v[j];
      }
  }
  *ntets = nt;
  *nverts = nv;
  return I2M_OK;
}

static void unnumber(struct submesh *S, const uint32_t *tets, uint32_t nt, const uint32_t *verts, uint32_t nv)
{
  for (uint32_t i = 0; i < nt; i++) S->tmark[tets[i]] = PACK_NONE;
  for (uint32_t i = 0; i < nv; i++) S->vmark[verts[i]] = PACK_NONE;
}

i2m_err_t i2m_refine_tile_kept_tets(i2m_refine_t *r, uint32_t id, int64_t *n)
{
  tile_t *tl = &r->tiling->tile[id];
  uint32_t *tets = NULL, *verts = NULL, nt = 0, nv = 0;
  *n = 0;
  if (!tl->held) return I2M_OK;
  I2M_CALL(sub_room(r->sub, r->dt));
  tile_compact(r->dt, tl);
  i2m_err_t err = number_submesh(r, tl, &tets, &nt, &verts, &nv); /* (each live tet once) */
  for (uint32_t k = 0; k < nt && err == I2M_OK; k++) *n += tet_kept(r->dt, tets[k]);
  unnumber(r->sub, tets, nt, verts, nv);
  i2m_free(&tets);
  i2m_free(&verts);
  return err;
}

/* A tile's bad elements (live, of its own tets) as buffer indices. */
static uint32_t pack_queue(const i2m_refine_t *r, const badlist_t *q, bytes_t *B)
{
  uint32_t n = 0;
  for (size_t i = 0; i < q->n; i++) {
    const uint32_t t = q->e[i][0];
    if (i2m_dt_stamp(r->dt, t) != q->e[i][1] || r->sub->tmark[t] == PACK_NONE) continue;
    bytes_put(B, &r->sub->tmark[t], sizeof(uint32_t));
    n++;
  }
  return n;
}

static uint32_t pack_pending(const pending_t *p, uint32_t n, bytes_t *B)
{
  for (uint32_t i = 0; i < n; i++) bytes_put(B, &(pack_pend_t){p[i].gid}, sizeof(pack_pend_t));
  return n;
}

/* The tet records; the cells across the external faces after them. */
static i2m_err_t pack_tets(const i2m_refine_t *r, const uint32_t *tets, uint32_t nt, bytes_t *B, int32_t **ext,
                           uint32_t *next, uint32_t *cap_ext)
{
  const struct submesh *S = r->sub;
  const i2m_dt_t *dt = r->dt;
  for (uint32_t k = 0; k < nt; k++) {
    const uint32_t t = tets[k];
    pack_tet_t rec;
    memset(&rec, 0, sizeof rec);
    for (int j = 0; j < 4; j++) rec.v[j] = S->vmark[dt->tv[4 * (size_t)t + j]];
    rec.label = tinfo(dt, t)->label;
    for (int i = 0; i < 4; i++) {
      const uint32_t n = dt->tn[4 * (size_t)t + i];
      if (n == I2M_DT_NONE) {
        rec.nb[i] = PACK_NONE;
        continue;
      }
      if (n < I2M_DT_REMOTE && S->tmark[n >> 2] != PACK_NONE) {
        rec.nb[i] = 4 * S->tmark[n >> 2] + (n & 3);
        continue;
      }
      int32_t cell;
      if (n == I2M_DT_REMOTE) {
        i2m_gidx_t key[3];
        face_key(dt, t, i, key);
        const rface_t *f = rf_find(S, key);
        I2M_CHECK(f, I2M_ERR_INTERNAL, "a face of another rank's is missing from the map");
        cell = f->cell;
      } else {
        cell = tile_of(r, n >> 2);
      }
      if (*next == *cap_ext) {
        *cap_ext = *cap_ext ? 2 * *cap_ext : 1024;
        I2M_CALL(i2m_realloc(*cap_ext, sizeof **ext, ext));
      }
      (*ext)[*next] = cell;
      rec.nb[i] = PACK_EXTERNAL | (*next)++;
    }
    bytes_put(B, &rec, sizeof rec);
  }
  return I2M_OK;
}

i2m_err_t i2m_refine_pack(i2m_refine_t *r, uint32_t id, void **buf, size_t *len)
{
  struct submesh *S = r->sub;
  const i2m_dt_t *dt = r->dt;
  tile_t *tl = &r->tiling->tile[id];
  uint32_t *tets = NULL, *verts = NULL, nt = 0, nv = 0, next = 0, cap_ext = 0;
  int32_t *ext = NULL;
  bytes_t B = {NULL, 0, 0, false};
  *buf = NULL;
  *len = 0;
  I2M_CHECK(tl->held, I2M_ERR_INTERNAL, "packing tile %u, which this rank does not hold", id);
  i2m_err_t err = number_submesh(r, tl, &tets, &nt, &verts, &nv);
  pack_header_t h;
  memset(&h, 0, sizeof h);
  h.magic = PACK_MAGIC;
  h.tile = id;
  h.ntets = nt;
  h.nverts = nv;
  h.gid_next = tl->gid_next;
  h.seq = tl->seq;
  h.grant = tl->grant;
  bytes_room(&B, sizeof h); /* (filled in last) */
  for (uint32_t k = 0; k < nv && err == I2M_OK; k++) {
    const uint32_t v = verts[k];
    pack_vertex_t pv;
    memset(&pv, 0, sizeof pv);
    pv.gid = i2m_dt_gid(dt, v);
    memcpy(pv.x, i2m_dt_xyz(dt, v), sizeof pv.x);
    pv.kind = dt->vkind[v];
    pv.tag = pv.kind == I2M_VK_SURFACE ? r->surf.tag[v] : 0;
    pv.near = is_near(r, v);
    bytes_put(&B, &pv, sizeof pv);
  }
  if (err == I2M_OK) err = pack_tets(r, tets, nt, &B, &ext, &next, &cap_ext);
  h.next = next;
  if (err == I2M_OK) bytes_put(&B, ext, next * sizeof *ext);
  for (int l = 0; l < NLEVELS && err == I2M_OK; l++) h.nq[l] = pack_queue(r, &tl->q[l], &B);
  for (int l = 0; l < NLEVELS && err == I2M_OK; l++) h.nwq[l] = pack_queue(r, &tl->wq[l], &B);
  if (err == I2M_OK) {
    h.npend = pack_pending(tl->pend, tl->npend, &B);
    h.nwpend = pack_pending(tl->wpend, tl->nwpend, &B);
    h.npts = tl->npts;
    h.nwpts = tl->nwpts;
    h.dirty = tl->dirty;
    bytes_put(&B, tl->pts, tl->npts * sizeof *tl->pts);
    bytes_put(&B, tl->wpts, tl->nwpts * sizeof *tl->wpts);
  }
  unnumber(S, tets, nt, verts, nv);
  i2m_free(&tets);
  i2m_free(&verts);
  i2m_free(&ext);
  if (err == I2M_OK && B.failed) err = I2M_ERROR(I2M_ERR_MEMORY, "out of memory packing a submesh of %u tets", nt);
  if (err != I2M_OK) {
    i2m_free(&B.b);
    return err;
  }
  memcpy(B.b, &h, sizeof h);
  *buf = B.b;
  *len = B.n;
  return I2M_OK;
}

/* ---- dropping a tile ---- */

/* A vertex that no local tet uses any more leaves the grids, the id map and the mesh. */
static i2m_err_t drop_vertex(i2m_refine_t *r, uint32_t v)
{
  i2m_dt_t *dt = r->dt;
  if (dt->vkind[v] == I2M_VK_SURFACE) vgrid_remove(&r->surf, dt, v);
  if (is_near(r, v)) vgrid_remove(&r->freev, dt, v);
  id_del(r->sub, i2m_dt_gid(dt, v));
  return i2m_dt_give_vertex(dt, v);
}

/* The vertices whose tet left while they still lie on a remote face of a local tet get that
 * tet: one pass over the remote faces for all of them (vmark flags them meanwhile). */
static void rehome_vertices(i2m_refine_t *r, const uint32_t *v, uint32_t n)
{
  struct submesh *S = r->sub;
  i2m_dt_t *dt = r->dt;
  uint32_t left = 0;
  for (uint32_t k = 0; k < n; k++)
    if (dt->vkind[v[k]] != I2M_VK_DEAD && S->vremote[v[k]] && !i2m_dt_alive(dt, dt->vtet[v[k]]) && S->vmark[v[k]] == PACK_NONE) {
      S->vmark[v[k]] = 0;
      left++;
    }
  for (size_t h = 0; h < S->cap_rf && left; h++) {
    const rface_t *f = &S->rf[h];
    if (f->key[0] < 0) continue;
    const uint32_t t = f->face >> 2, *tv = dt->tv + 4 * (size_t)t;
    for (int j = 0; j < 3; j++) {
      const uint32_t w = tv[FACE_V[f->face & 3][j]];
      if (S->vmark[w] != 0) continue;
      dt->vtet[w] = t;
      S->vmark[w] = PACK_NONE;
      left--;
    }
  }
  for (uint32_t k = 0; k < n; k++) S->vmark[v[k]] = PACK_NONE;
}

/* One tile leaves; the vertices that need another tet are added to *lost. */
static i2m_err_t drop_tile(i2m_refine_t *r, uint32_t id, uint32_t **lost, uint32_t *nlost, uint32_t *cap_lost)
{
  struct submesh *S = r->sub;
  i2m_dt_t *dt = r->dt;
  tile_t *tl = &r->tiling->tile[id];
  uint32_t *tets = NULL, *verts = NULL, nt = 0, nv = 0;
  i2m_err_t err = number_submesh(r, tl, &tets, &nt, &verts, &nv);
  for (uint32_t k = 0; k < nt && err == I2M_OK; k++) { /* faces to the tets that stay become remote */
    const uint32_t t = tets[k];
    for (int i = 0; i < 4 && err == I2M_OK; i++) {
      const uint32_t n = dt->tn[4 * (size_t)t + i];
      if (n == I2M_DT_NONE || (n < I2M_DT_REMOTE && S->tmark[n >> 2] != PACK_NONE)) continue;
      if (n == I2M_DT_REMOTE) {
        i2m_gidx_t key[3];
        face_key(dt, t, i, key);
        rface_t *f = rf_find(S, key);
        if (f) rf_del(S, f);
        vremote_add(S, dt, t, i, -1);
        continue;
      }
      const uint32_t u = n >> 2;
      err = make_remote(S, dt, u, (int)(n & 3), (int32_t)id);
      const uint32_t *uv = dt->tv + 4 * (size_t)u;
      for (int j = 0; j < 3; j++) dt->vtet[uv[FACE_V[n & 3][j]]] = u; /* (they stay: u holds them) */
    }
  }
  for (uint32_t k = 0; k < nt && err == I2M_OK; k++) err = i2m_dt_give_tet(dt, tets[k]);
  for (uint32_t k = 0; k < nv && err == I2M_OK; k++) {
    const uint32_t v = verts[k];
    if (v >= 8 && S->vremote[v] == 0) {
      err = drop_vertex(r, v); /* (the box corners are every rank's) */
    } else if (S->vremote[v] && !i2m_dt_alive(dt, dt->vtet[v])) {
      if (*nlost == *cap_lost) {
        *cap_lost = *cap_lost ? 2 * *cap_lost : 256;
        err = i2m_realloc(*cap_lost, sizeof **lost, lost);
      }
      if (err == I2M_OK) (*lost)[(*nlost)++] = v;
    }
  }
  unnumber(S, tets, nt, verts, nv);
  i2m_free(&tets);
  i2m_free(&verts);
  for (int l = 0; l < NLEVELS; l++) tl->q[l].n = tl->wq[l].n = 0;
  tl->npend = tl->nwpend = 0;
  tl->npts = tl->nwpts = 0;
  tl->dirty = false;
  tl->ntets = tl->live_tets = 0;
  tl->held = false;
  return err;
}

i2m_err_t i2m_refine_drop(i2m_refine_t *r, const uint32_t *ids, uint32_t n)
{
  uint32_t *lost = NULL, nlost = 0, cap_lost = 0;
  if (n == 0) return I2M_OK;
  pieces_invalidate(r);
  I2M_CALL(sub_room(r->sub, r->dt));
  i2m_err_t err = I2M_OK;
  for (uint32_t k = 0; k < n && err == I2M_OK; k++) err = drop_tile(r, ids[k], &lost, &nlost, &cap_lost);
  if (err == I2M_OK) rehome_vertices(r, lost, nlost);
  i2m_free(&lost);
  return err;
}

/* ---- unpacking ---- */

typedef struct {
  const unsigned char *p, *end;
} reader_t;

static const void *take(reader_t *R, size_t k)
{
  if ((size_t)(R->end - R->p) < k) return NULL;
  const void *x = R->p;
  R->p += k;
  return x;
}

/* The local slot of each vertex of the buffer (existing ones by global id). */
static i2m_err_t unpack_vertices(i2m_refine_t *r, const pack_vertex_t *pv, uint32_t nv, uint32_t *slot)
{
  struct submesh *S = r->sub;
  i2m_dt_t *dt = r->dt;
  for (uint32_t k = 0; k < nv; k++) {
    uint32_t v = pv[k].gid >= 0 && pv[k].gid < 8 ? (uint32_t)pv[k].gid : id_find(S, pv[k].gid);
    if (v != PACK_NONE && dt->vkind[v] != I2M_VK_DEAD && i2m_dt_gid(dt, v) == pv[k].gid) {
      const double *x = i2m_dt_xyz(dt, v);
      I2M_CHECK(x[0] == pv[k].x[0] && x[1] == pv[k].x[1] && x[2] == pv[k].x[2], I2M_ERR_INTERNAL,
                "vertex %lld arrives at another place than where this rank has it", (long long)pv[k].gid);
      slot[k] = v;
      continue;
    }
    I2M_CALL(i2m_dt_take_vertex(dt, &v));
    I2M_CALL(sub_room(S, dt));
    double *x = dt->xyzw + 4 * (size_t)v;
    memcpy(x, pv[k].x, sizeof pv[k].x);
    union { double d; int64_t i; } u;
    u.i = pv[k].gid;
    x[3] = u.d;
    dt->vkind[v] = pv[k].kind;
    S->vremote[v] = 0;
    I2M_CALL(id_put(S, pv[k].gid, v));
    if (pv[k].kind == I2M_VK_SURFACE) I2M_CALL(vgrid_insert(&r->surf, dt, v, pv[k].tag));
    if (pv[k].near) I2M_CALL(vgrid_insert(&r->freev, dt, v, VGRID_MEMBER));
    slot[k] = v;
  }
  return I2M_OK;
}

/* The tets of the buffer: slots, vertices, labels, inner faces; then every external face is
 * matched with a remote face of a local tet (both become inner) or becomes remote. */
static i2m_err_t unpack_tets(i2m_refine_t *r, tile_t *tl, const pack_tet_t *pt, uint32_t nt, const int32_t *ext,
                             uint32_t next, const uint32_t *vslot, uint32_t *tslot)
{
  struct submesh *S = r->sub;
  i2m_dt_t *dt = r->dt;
  for (uint32_t k = 0; k < nt; k++) {
    I2M_CALL(i2m_dt_take_tet(dt, &tslot[k]));
    const uint32_t t = tslot[k];
    for (int j = 0; j < 4; j++) {
      I2M_CHECK(pt[k].v[j] < UINT32_MAX && vslot[pt[k].v[j]] != PACK_NONE, I2M_ERR_INTERNAL, "bad submesh");
      dt->tv[4 * (size_t)t + j] = vslot[pt[k].v[j]];
    }
    tinfo(dt, t)->label = pt[k].label;
  }
  I2M_CALL(sub_room(S, dt));
  for (uint32_t k = 0; k < nt; k++) {
    const uint32_t t = tslot[k];
    for (int j = 0; j < 4; j++) dt->vtet[dt->tv[4 * (size_t)t + j]] = t;
    for (int i = 0; i < 4; i++) {
      const uint32_t nb = pt[k].nb[i];
      if (nb == PACK_NONE) {
        dt->tn[4 * (size_t)t + i] = I2M_DT_NONE;
      } else if (!(nb & PACK_EXTERNAL)) {
        I2M_CHECK((nb >> 2) < nt, I2M_ERR_INTERNAL, "bad submesh");
        dt->tn[4 * (size_t)t + i] = 4 * tslot[nb >> 2] + (nb & 3);
      } else {
        const uint32_t e = nb & ~PACK_EXTERNAL;
        I2M_CHECK(e < next, I2M_ERR_INTERNAL, "bad submesh");
        i2m_gidx_t key[3];
        face_key(dt, t, i, key);
        rface_t *f = rf_find(S, key);
        if (f) { /* a local tet waited for it across that face */
          const uint32_t other = f->face;
          vremote_add(S, dt, other >> 2, (int)(other & 3), -1);
          rf_del(S, f);
          dt->tn[4 * (size_t)t + i] = other;
          dt->tn[other] = 4 * t + (uint32_t)i;
        } else {
          I2M_CALL(make_remote(S, dt, t, i, ext[e]));
        }
      }
    }
    I2M_CALL(tile_file(tl, t, i2m_dt_stamp(dt, t)));
  }
  tl->live_tets = tl->ntets;
  return I2M_OK;
}

static i2m_err_t unpack_queue(i2m_refine_t *r, badlist_t *q, reader_t *R, uint32_t n, const uint32_t *tslot, uint32_t nt)
{
  for (uint32_t i = 0; i < n; i++) {
    const uint32_t *k = take(R, sizeof *k);
    I2M_CHECK(k && *k < nt, I2M_ERR_INTERNAL, "bad submesh (queue)");
    bad_t b = {tslot[*k], i2m_dt_stamp(r->dt, tslot[*k]), {0, 0, 0, 0}};
    I2M_CALL(badlist_push(q, r->dt, &b));
  }
  return I2M_OK;
}

/* Pending removals: the vertex by its global id (PACK_NONE when this rank has none such: the
 * task that tries it finds it then, or defers it). */
static i2m_err_t unpack_pending(i2m_refine_t *r, pending_t **a, uint32_t *n, uint32_t *cap, reader_t *R, uint32_t k)
{
  for (uint32_t i = 0; i < k; i++) {
    const pack_pend_t *p = take(R, sizeof *p);
    I2M_CHECK(p, I2M_ERR_INTERNAL, "bad submesh (pending)");
    if (*n == *cap) {
      *cap = *cap ? 2 * *cap : 64;
      I2M_CALL(i2m_realloc(*cap, sizeof **a, a));
    }
    (*a)[(*n)++] = (pending_t){id_find(r->sub, p->gid), p->gid};
  }
  return I2M_OK;
}

i2m_err_t i2m_refine_unpack(i2m_refine_t *r, const void *buf, size_t len, uint32_t *tile)
{
  reader_t R = {buf, (const unsigned char *)buf + len};
  const pack_header_t *hp = take(&R, sizeof *hp);
  I2M_CHECK(hp && hp->magic == PACK_MAGIC && hp->tile < r->tiling->ntiles, I2M_ERR_INTERNAL, "bad submesh (header)");
  const pack_header_t h = *hp;
  tile_t *tl = &r->tiling->tile[h.tile];
  I2M_CHECK(!tl->held, I2M_ERR_INTERNAL, "tile %u arrives at a rank that holds it", h.tile);
  pieces_invalidate(r);
  const pack_vertex_t *pv = take(&R, (size_t)h.nverts * sizeof *pv);
  const pack_tet_t *pt = take(&R, (size_t)h.ntets * sizeof *pt);
  const int32_t *ext = take(&R, (size_t)h.next * sizeof *ext);
  I2M_CHECK(pv && pt && ext, I2M_ERR_INTERNAL, "bad submesh (truncated)");
  uint32_t *vslot = NULL, *tslot = NULL;
  i2m_err_t err = i2m_malloc(h.nverts ? h.nverts : 1, sizeof *vslot, &vslot);
  if (err == I2M_OK) err = i2m_malloc(h.ntets ? h.ntets : 1, sizeof *tslot, &tslot);
  if (err == I2M_OK) err = unpack_vertices(r, pv, h.nverts, vslot);
  if (err == I2M_OK) err = unpack_tets(r, tl, pt, h.ntets, ext, h.next, vslot, tslot);
  for (int l = 0; l < NLEVELS && err == I2M_OK; l++) err = unpack_queue(r, &tl->q[l], &R, h.nq[l], tslot, h.ntets);
  for (int l = 0; l < NLEVELS && err == I2M_OK; l++) err = unpack_queue(r, &tl->wq[l], &R, h.nwq[l], tslot, h.ntets);
  if (err == I2M_OK) err = unpack_pending(r, &tl->pend, &tl->npend, &tl->cap_pend, &R, h.npend);
  if (err == I2M_OK) err = unpack_pending(r, &tl->wpend, &tl->nwpend, &tl->cap_wpend, &R, h.nwpend);
  const unsigned char *pts = take(&R, (size_t)h.npts * sizeof(i2m_bridge_point_t));
  const unsigned char *wpts = take(&R, (size_t)h.nwpts * sizeof(i2m_bridge_point_t));
  if (err == I2M_OK && !(pts && wpts)) err = I2M_ERROR(I2M_ERR_INTERNAL, "bad submesh (truncated points)");
  for (uint32_t i = 0; i < h.npts + h.nwpts && err == I2M_OK; i++) { /* (copied out: the buffer is not aligned) */
    i2m_bridge_point_t p;
    memcpy(&p, i < h.npts ? pts + i * sizeof p : wpts + (i - h.npts) * sizeof p, sizeof p);
    err = tiles_add_point(r, h.tile, &p, i >= h.npts);
  }
  tl->dirty = h.dirty != 0;
  i2m_free(&vslot);
  i2m_free(&tslot);
  I2M_CALL(err);
  tl->gid_next = h.gid_next;
  tl->seq = h.seq;
  tl->grant = h.grant;
  tl->held = true;
  slivers_forget_tile(r, h.tile);
  if (tile) *tile = h.tile;
  return I2M_OK;
}

/* ---- pending removals whose vertex was not here when they arrived ---- */

void i2m_refine_dist_resolve(i2m_refine_t *r, uint32_t id)
{
  tile_t *tl = &r->tiling->tile[id];
  pending_t *lists[2] = {tl->pend, tl->wpend};
  const uint32_t n[2] = {tl->npend, tl->nwpend};
  for (int k = 0; k < 2; k++)
    for (uint32_t i = 0; i < n[k]; i++)
      if (lists[k][i].v == PACK_NONE) lists[k][i].v = id_find(r->sub, lists[k][i].gid);
}

/* ---- the labels across the faces of other ranks' (for extraction, pieces and fragments) ---- */

size_t i2m_refine_dist_nfaces(const i2m_refine_t *r) { return r->sub ? r->sub->nrf : 0; }

bool dist_next_remote_face(const i2m_refine_t *r, size_t *h, uint32_t *face, i2m_gidx_t key[3], int32_t *cell)
{
  const struct submesh *S = r->sub;
  for (; S && *h < S->cap_rf; ++*h) {
    const rface_t *f = &S->rf[*h];
    if (f->key[0] < 0) continue;
    *face = f->face;
    memcpy(key, f->key, sizeof f->key);
    *cell = f->cell;
    ++*h;
    return true;
  }
  return false;
}

void i2m_refine_dist_faces(const i2m_refine_t *r, i2m_face_label_t *out)
{
  size_t n = 0, h = 0;
  uint32_t face;
  i2m_face_label_t f;
  memset(&f, 0, sizeof f); /* (its padding too: the records travel as bytes) */
  while (dist_next_remote_face(r, &h, &face, f.key, &f.cell)) {
    f.label = tinfo(r->dt, face >> 2)->label;
    out[n++] = f;
  }
}

int64_t i2m_refine_dist_ghosts(i2m_refine_t *r, const i2m_face_label_t *faces, size_t n)
{
  int64_t unknown = 0;
  for (size_t k = 0; k < n; k++) {
    rface_t *f = rf_find(r->sub, faces[k].key);
    if (f) f->ghost = faces[k].label;
    else unknown++;
  }
  return unknown;
}

uint16_t dist_ghost_label(const i2m_refine_t *r, uint32_t t, int i)
{
  i2m_gidx_t key[3];
  face_key(r->dt, t, i, key);
  const rface_t *f = rf_find(r->sub, key);
  return f ? f->ghost : 0;
}

uint32_t dist_face_at(const i2m_refine_t *r, const i2m_gidx_t key[3])
{
  const rface_t *f = rf_find(r->sub, key);
  return f ? f->face : I2M_DT_NONE;
}

