/* Refine layer: the pieces of the labelled mesh and the image components they stand for, on
 * one process or across ranks.
 *
 * A piece is a face-connected set of kept tets of one label.  Each process finds the pieces of
 * its own tets (its parts) with a union-find over the tet slots, in parallel (compare-and-swap
 * links, always from the larger root to the smaller); a part says what the whole needs of it:
 * label, tets, volume, its least tet (sorted global ids: a key that no rank or thread order
 * changes), the volume it has in each image component (by the voxel of each tet's
 * circumcentre: a Delaunay image mesh labels a tet there), and, for small parts, the face area
 * it shares with each other label.  Parts across a face between ranks are joined by the dist
 * layer (their faces there, i2m_part_face_t).  i2m_pieces_resolve then makes the pieces of the
 * whole mesh (groups) from every part, pure arithmetic that every process count does alike:
 * each group stands for the component that holds the circumcentres of most of its volume;
 * fragments (fragments.c) and the components the mesh splits (bridges.c) follow from them,
 * and a census per label for the report. */
#include "refine_impl.h"

#include <stdlib.h>
#include <string.h>

/* ---- union-find over tet slots ---- */

static uint32_t uf_find(_Atomic uint32_t *par, uint32_t x)
{
  for (;;) {
    uint32_t p = atomic_load_explicit(&par[x], memory_order_relaxed);
    if (p == x) return x;
    uint32_t g = atomic_load_explicit(&par[p], memory_order_relaxed);
    if (g != p) /* path halving: any ancestor is a valid parent */
      atomic_compare_exchange_weak_explicit(&par[x], &p, g, memory_order_relaxed, memory_order_relaxed);
    x = g;
  }
}

static void uf_union(_Atomic uint32_t *par, uint32_t a, uint32_t b)
{
  for (;;) {
    a = uf_find(par, a);
    b = uf_find(par, b);
    if (a == b) return;
    if (a < b) {
      uint32_t x = a;
      a = b;
      b = x;
    }
    uint32_t expected = a; /* link the larger root under the smaller, if it is still a root */
    if (atomic_compare_exchange_strong_explicit(&par[a], &expected, b, memory_order_relaxed, memory_order_relaxed))
      return;
  }
}

/* Progress of the passes over the tet slots: a line every 2 s (i2m_progress_add), each thread
 * adding its share every PROGRESS_STEP slots (a power of two). */
#define PROGRESS_STEP 65536
static inline void slot_done(i2m_progress_t *pg, int64_t t)
{
  if ((t & (PROGRESS_STEP - 1)) == PROGRESS_STEP - 1) i2m_progress_add(pg, PROGRESS_STEP);
}

/* par[t] = the smallest slot of t's part. */
static void find_parts(const i2m_dt_t *dt, _Atomic uint32_t *par, i2m_progress_t *pg)
{
  const int64_t n = i2m_dt_ntets_slots(dt);
  I2M_OMP(omp parallel)
  {
    I2M_OMP(omp for schedule(static))
    for (int64_t t = 0; t < n; t++) atomic_init(&par[t], (uint32_t)t);
    I2M_OMP(omp for schedule(dynamic, 4096))
    for (int64_t t = 0; t < n; t++) {
      slot_done(pg, t);
      if (!tet_kept(dt, (uint32_t)t)) continue;
      const uint16_t l = tinfo(dt, (uint32_t)t)->label;
      for (int i = 0; i < 4; i++) {
        uint32_t nb = dt->tn[4 * (size_t)t + i];
        if (nb >= I2M_DT_REMOTE || (nb >> 2) > (uint32_t)t) continue; /* each face once (another rank's: the dist layer) */
        if (tinfo(dt, nb >> 2)->label == l) uf_union(par, (uint32_t)t, nb >> 2); /* (a neighbour is alive) */
      }
    }
    I2M_OMP(omp for schedule(static))
    for (int64_t t = 0; t < n; t++)
      if (tet_kept(dt, (uint32_t)t)) atomic_store_explicit(&par[t], uf_find(par, (uint32_t)t), memory_order_relaxed);
  }
}

double pieces_tet_volume(const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  return i2m_tet_signed_volume6(i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]),
                                i2m_dt_xyz(dt, v[3])) / 6.0;
}

/* ---- keys: a tet by its sorted global ids, compared lexicographically ---- */

void pieces_tet_key(const i2m_dt_t *dt, uint32_t t, i2m_gidx_t k[4])
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (int i = 0; i < 4; i++) k[i] = i2m_dt_gid(dt, v[i]);
  for (int a = 1; a < 4; a++)
    for (int b = a; b > 0 && k[b] < k[b - 1]; b--) {
      const i2m_gidx_t x = k[b];
      k[b] = k[b - 1];
      k[b - 1] = x;
    }
}

int pieces_key_cmp(const i2m_gidx_t a[4], const i2m_gidx_t b[4])
{
  for (int i = 0; i < 4; i++)
    if (a[i] != b[i]) return a[i] < b[i] ? -1 : 1;
  return 0;
}

static void key_min(i2m_gidx_t acc[4], const i2m_gidx_t k[4])
{
  if (pieces_key_cmp(k, acc) < 0) memcpy(acc, k, 4 * sizeof *acc);
}

/* ---- the parts of the local mesh ---- */

/* The image component of voxel-frame point u if its voxel has label index lab, else -1.  The
 * label comes from the components' runs (built over the transform's block K, with its labels),
 * not from the transform's words: a tet's circumcentre falls anywhere in a large array, the
 * runs of its row are small (the describe pass took 85% of its time in that one load). */
static int64_t component_at(const i2m_refine_t *r, const double u[3], int lab)
{
  int64_t v[3];
  if (!i2m_edt_image_voxel_k(r->edt, u, v)) return -1;
  return i2m_components_find_label(&r->pieces_ic, v[0], v[1], v[2], lab);
}

/* The component tet t stands for: that of its circumcentre, if it lies in its label (-1). */
static int64_t tet_component(const i2m_refine_t *r, uint32_t t)
{
  tet_geom_t g;
  tet_centre(r, t, &g); /* (a flat tet's u is NaN: no voxel) */
  return component_at(r, g.u, tinfo(r->dt, t)->label);
}

/* The part table (roots in slot order); par[t] becomes t's part index. */
static i2m_err_t list_parts(const i2m_refine_t *r, pieces_t *P)
{
  const i2m_dt_t *dt = r->dt;
  const uint32_t n = i2m_dt_ntets_slots(dt);
  size_t cap = 0;
  for (uint32_t t = 0; t < n; t++) {
    if (!tet_kept(dt, t) || atomic_load_explicit(&P->par[t], memory_order_relaxed) != t) continue;
    if (P->nparts == cap) {
      cap = 2 * cap + 256;
      I2M_CALL(i2m_realloc(cap, sizeof *P->part, &P->part));
      I2M_CALL(i2m_realloc(cap, sizeof *P->root, &P->root));
    }
    i2m_part_t *p = &P->part[P->nparts];
    memset(p, 0, sizeof *p);
    p->label = tinfo(dt, t)->label;
    for (int i = 0; i < 4; i++) p->key[i] = INT64_MAX;
    P->root[P->nparts] = t;
    atomic_store_explicit(&P->idx[t], (uint32_t)P->nparts, memory_order_relaxed); /* (the root's index, for now) */
    P->nparts++;
  }
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t t = 0; t < (int64_t)n; t++) { /* every tet's part index, from its root */
    if (!tet_kept(dt, (uint32_t)t)) continue;
    const uint32_t root = atomic_load_explicit(&P->par[t], memory_order_relaxed);
    atomic_store_explicit(&P->par[t], atomic_load_explicit(&P->idx[root], memory_order_relaxed), memory_order_relaxed);
  }
  return I2M_OK;
}

/* A small open hash from nonzero 64-bit keys to the indices of entries in the order they came. */
typedef struct {
  uint64_t *key; /* 0: empty */
  uint32_t *at;
  size_t cap, n;
} key_index_t;

static size_t key_slot(const key_index_t *H, uint64_t k)
{
  size_t h = (size_t)((k * 0x9E3779B97F4A7C15ull) >> 17) & (H->cap - 1);
  while (H->key[h] && H->key[h] != k) h = (h + 1) & (H->cap - 1);
  return h;
}

/* Key k's index into *at; a new key gets the next one (*added). */
static i2m_err_t key_index(key_index_t *H, uint64_t k, uint32_t *at, bool *added)
{
  if (2 * (H->n + 1) > H->cap) { /* rehash */
    key_index_t G = {NULL, NULL, H->cap ? 2 * H->cap : 64, H->n};
    I2M_CALL(i2m_calloc(G.cap, sizeof *G.key, &G.key));
    i2m_err_t err = i2m_malloc(G.cap, sizeof *G.at, &G.at);
    if (err != I2M_OK) {
      i2m_free(&G.key);
      return err;
    }
    for (size_t i = 0; i < H->cap; i++)
      if (H->key[i]) {
        const size_t h = key_slot(&G, H->key[i]);
        G.key[h] = H->key[i];
        G.at[h] = H->at[i];
      }
    i2m_free(&H->key);
    i2m_free(&H->at);
    *H = G;
  }
  const size_t h = key_slot(H, k);
  *added = !H->key[h];
  if (*added) {
    H->key[h] = k;
    H->at[h] = (uint32_t)H->n++;
  }
  *at = H->at[h];
  return I2M_OK;
}

static void key_index_free(key_index_t *H)
{
  i2m_free(&H->key);
  i2m_free(&H->at);
}

/* ---- a part's figures, summed by chunks of slots in parallel ---- */

/* Slots per chunk: the sums of a chunk are taken in slot order and the chunks' in chunk order,
 * so the figures do not depend on the number of threads. */
#define DESCRIBE_CHUNK 65536

/* A chunk's sums for one part, or for one (part, image component) pair (comp: the component's
 * root run, as idx[] holds it), each with its least tet (seed: its slot). */
typedef struct {
  i2m_gidx_t key[4];
  double volume;
  int64_t ntets;
  uint32_t part, comp, seed;
} part_sum_t;

typedef struct {
  part_sum_t *part, *comp; /* in the order the chunk first met them */
  uint32_t nparts, ncomps;
  i2m_err_t err;
} chunk_sums_t;

static i2m_err_t sum_entry(key_index_t *H, uint64_t k, part_sum_t **v, uint32_t *n, size_t *cap, part_sum_t **out)
{
  uint32_t at;
  bool added;
  I2M_CALL(key_index(H, k, &at, &added));
  if (added) {
    if (*n == *cap) {
      *cap = 2 * *cap + 16;
      I2M_CALL(i2m_realloc(*cap, sizeof **v, v));
    }
    part_sum_t *e = &(*v)[(*n)++];
    memset(e, 0, sizeof *e);
    for (int i = 0; i < 4; i++) e->key[i] = INT64_MAX;
    e->seed = UINT32_MAX;
  }
  *out = &(*v)[at];
  return I2M_OK;
}

/* Tet t into sums e (its key k computed once, when it may be the least: low is its least id). */
static void sum_tet(const i2m_dt_t *dt, uint32_t t, double v, i2m_gidx_t low, i2m_gidx_t k[4], part_sum_t *e)
{
  e->ntets++;
  e->volume += v;
  if (low > e->key[0]) return; /* a key begins with the least id: most tets lose there */
  if (k[0] == INT64_MAX) pieces_tet_key(dt, t, k);
  if (pieces_key_cmp(k, e->key) < 0) {
    memcpy(e->key, k, 4 * sizeof *k);
    e->seed = t;
  }
}

/* Slots [t0, t1): each kept tet's component into idx[t], and the chunk's sums. */
static void sum_chunk(const i2m_refine_t *r, pieces_t *P, uint32_t t0, uint32_t t1, chunk_sums_t *out)
{
  const i2m_dt_t *dt = r->dt;
  key_index_t Hp = {NULL, NULL, 0, 0}, Hc = {NULL, NULL, 0, 0}; /* (the entries of each list) */
  size_t cap_parts = 0, cap_comps = 0;
  part_sum_t *ep = NULL, *ec = NULL;
  uint32_t last_part = UINT32_MAX, last_comp = UINT32_MAX; /* (neighbouring slots: often one entry) */
  i2m_err_t err = I2M_OK;
  for (uint32_t t = t0; t < t1 && err == I2M_OK; t++) {
    if (!tet_kept(dt, t)) continue;
    const int64_t comp = tet_component(r, t);
    const uint32_t c = comp < 0 || comp >= UINT32_MAX ? UINT32_MAX : (uint32_t)comp;
    atomic_store_explicit(&P->idx[t], c, memory_order_relaxed);
    const uint32_t pi = atomic_load_explicit(&P->par[t], memory_order_relaxed);
    if (pi != last_part) err = sum_entry(&Hp, (uint64_t)pi + 1, &out->part, &out->nparts, &cap_parts, &ep);
    if (err == I2M_OK && c != UINT32_MAX && (pi != last_part || c != last_comp))
      err = sum_entry(&Hc, (uint64_t)(pi + 1) << 32 | c, &out->comp, &out->ncomps, &cap_comps, &ec);
    if (err != I2M_OK) break;
    last_part = pi;
    last_comp = c;
    ep->part = pi;
    const double v = fabs(pieces_tet_volume(dt, t));
    const uint32_t *tv = dt->tv + 4 * (size_t)t;
    i2m_gidx_t low = i2m_dt_gid(dt, tv[0]);
    for (int i = 1; i < 4; i++) low = i2m_dt_gid(dt, tv[i]) < low ? i2m_dt_gid(dt, tv[i]) : low;
    i2m_gidx_t k[4] = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
    sum_tet(dt, t, v, low, k, ep);
    if (c == UINT32_MAX) continue;
    ec->part = pi;
    ec->comp = c;
    sum_tet(dt, t, v, low, k, ec);
  }
  key_index_free(&Hp);
  key_index_free(&Hc);
  out->err = err;
}

/* Every part's tets, volume, least tet, and volume per image component (with the least tet in
 * each, where the bridges' search starts); tet t's component into idx[t].  The comp table
 * lists the pairs in the order of the slots that first meet them. */
static i2m_err_t describe_parts(const i2m_refine_t *r, pieces_t *P, i2m_progress_t *pg)
{
  const uint32_t n = i2m_dt_ntets_slots(r->dt);
  const int64_t nchunks = ((int64_t)n + DESCRIBE_CHUNK - 1) / DESCRIBE_CHUNK;
  chunk_sums_t *sums = NULL;
  I2M_CALL(i2m_calloc((size_t)nchunks + 1, sizeof *sums, &sums));
  I2M_OMP(omp parallel for schedule(dynamic, 1))
  for (int64_t j = 0; j < nchunks; j++) {
    const uint32_t t0 = (uint32_t)(j * DESCRIBE_CHUNK), t1 = t0 + DESCRIBE_CHUNK < n ? t0 + DESCRIBE_CHUNK : n;
    sum_chunk(r, P, t0, t1, &sums[j]);
    i2m_progress_add(pg, 2 * (int64_t)(t1 - t0)); /* (two of the three passes the progress counts) */
  }
  key_index_t H = {NULL, NULL, 0, 0};
  size_t cap_comp = 0;
  i2m_err_t err = I2M_OK;
  for (int64_t j = 0; j < nchunks && err == I2M_OK; j++) { /* merged in chunk order */
    const chunk_sums_t *s = &sums[j];
    err = s->err;
    for (uint32_t i = 0; i < s->nparts && err == I2M_OK; i++) {
      const part_sum_t *e = &s->part[i];
      i2m_part_t *p = &P->part[e->part];
      p->ntets += e->ntets;
      p->volume += e->volume;
      key_min(p->key, e->key);
    }
    for (uint32_t i = 0; i < s->ncomps && err == I2M_OK; i++) {
      const part_sum_t *e = &s->comp[i];
      uint32_t at;
      bool added;
      err = key_index(&H, (uint64_t)(e->part + 1) << 32 | e->comp, &at, &added);
      if (err == I2M_OK && added && P->ncomps == cap_comp) {
        cap_comp = 2 * cap_comp + 256;
        err = i2m_realloc(cap_comp, sizeof *P->comp, &P->comp);
      }
      if (err != I2M_OK) break;
      i2m_part_comp_t *c = &P->comp[at];
      if (added) {
        c->part = e->part;
        c->comp = e->comp;
        c->volume = 0;
        c->seed = UINT32_MAX;
        for (int k = 0; k < 4; k++) c->key[k] = INT64_MAX;
        P->ncomps++;
      }
      c->volume += e->volume;
      if (pieces_key_cmp(e->key, c->key) < 0) {
        memcpy(c->key, e->key, sizeof c->key);
        c->seed = e->seed;
      }
    }
  }
  for (int64_t j = 0; j < nchunks; j++) {
    i2m_free(&sums[j].part);
    i2m_free(&sums[j].comp);
  }
  i2m_free(&sums);
  key_index_free(&H);
  for (size_t i = 0; i < P->nparts; i++) P->part[i].small = P->part[i].ntets <= pieces_small_tets(r);
  return err;
}

/* The face area each small part shares with each other label (0: outside the mesh), across
 * faces between ranks too (the labels there, i2m_refine_dist_ghosts). */
static i2m_err_t describe_areas(const i2m_refine_t *r, pieces_t *P)
{
  static const int FACE[4][3] = {{1, 2, 3}, {0, 2, 3}, {0, 1, 3}, {0, 1, 2}};
  const i2m_dt_t *dt = r->dt;
  const uint32_t n = i2m_dt_ntets_slots(dt);
  size_t cap = 0;
  for (uint32_t t = 0; t < n; t++) {
    if (!tet_kept(dt, t)) continue;
    const uint32_t pi = atomic_load_explicit(&P->par[t], memory_order_relaxed);
    if (!P->part[pi].small) continue;
    const uint16_t l = tinfo(dt, t)->label;
    const uint32_t *v = dt->tv + 4 * (size_t)t;
    for (int i = 0; i < 4; i++) {
      const uint32_t nb = dt->tn[4 * (size_t)t + i];
      const uint16_t m = nb == I2M_DT_NONE ? 0 : nb == I2M_DT_REMOTE ? dist_ghost_label(r, t, i) : tinfo(dt, nb >> 2)->label;
      if (m == l) continue; /* a face inside the piece */
      const double *a = i2m_dt_xyz(dt, v[FACE[i][0]]), *b = i2m_dt_xyz(dt, v[FACE[i][1]]), *d = i2m_dt_xyz(dt, v[FACE[i][2]]);
      const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
      const double x = u[1] * w[2] - u[2] * w[1], y = u[2] * w[0] - u[0] * w[2], z = u[0] * w[1] - u[1] * w[0];
      if (P->nareas == cap) {
        cap = 2 * cap + 256;
        I2M_CALL(i2m_realloc(cap, sizeof *P->area, &P->area));
      }
      P->area[P->nareas++] = (i2m_part_area_t){.area = sqrt(x * x + y * y + z * z), .part = pi, .label = m};
    }
  }
  return I2M_OK;
}

/* The faces between a local kept tet and another rank's (the dist layer joins parts there),
 * from the table of those faces. */
static i2m_err_t describe_faces(const i2m_refine_t *r, pieces_t *P)
{
  const i2m_dt_t *dt = r->dt;
  size_t cap = 0, h = 0;
  uint32_t face;
  i2m_gidx_t key[3];
  int32_t cell;
  while (dist_next_remote_face(r, &h, &face, key, &cell)) {
    const uint32_t t = face >> 2;
    if (!tet_kept(dt, t)) continue;
    if (P->nfaces == cap) {
      cap = 2 * cap + 256;
      I2M_CALL(i2m_realloc(cap, sizeof *P->face, &P->face));
    }
    i2m_part_face_t *f = &P->face[P->nfaces++];
    memcpy(f->key, key, sizeof f->key);
    f->cell = cell;
    f->part = atomic_load_explicit(&P->par[t], memory_order_relaxed);
    f->label = tinfo(dt, t)->label;
  }
  return I2M_OK;
}

i2m_err_t pieces_build(i2m_refine_t *r, pieces_t *P)
{
  const i2m_dt_t *dt = r->dt;
  const uint32_t n = i2m_dt_ntets_slots(dt);
  memset(P, 0, sizeof *P);
  if (!r->pieces_ic.nruns) I2M_CALL(i2m_edt_components(r->edt, &r->pieces_ic));
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, fail, i2m_malloc(n ? n : 1, sizeof *P->par, &P->par));
  I2M_CALL_GOTO(err, fail, i2m_malloc(n ? n : 1, sizeof *P->idx, &P->idx));
  i2m_progress_t pg; /* (three passes over the slots: most of the time on large meshes) */
  i2m_progress_begin_total(&pg, "mesh pieces (components per label)", "tet slots", 3 * (int64_t)n);
  double t[6];
  t[0] = i2m_wtime();
  find_parts(dt, P->par, &pg);
  t[1] = i2m_wtime();
  I2M_CALL_GOTO(err, fail, list_parts(r, P));
  t[2] = i2m_wtime();
  I2M_CALL_GOTO(err, fail, describe_parts(r, P, &pg));
  t[3] = i2m_wtime();
  I2M_CALL_GOTO(err, fail, describe_areas(r, P));
  t[4] = i2m_wtime();
  I2M_CALL_GOTO(err, fail, describe_faces(r, P));
  t[5] = i2m_wtime();
  i2m_progress_end(&pg, 3 * (int64_t)n);
  i2m_debug("pieces: %u tet slots, %zu parts; find %.2f s, list %.2f s, describe %.2f s, areas %.2f s, faces %.2f s", n,
            P->nparts, t[1] - t[0], t[2] - t[1], t[3] - t[2], t[4] - t[3], t[5] - t[4]);
  return I2M_OK;
fail:
  pieces_free(P);
  return err;
}

i2m_err_t pieces_get(i2m_refine_t *r, pieces_t **out)
{
  if (!r->pieces_valid) {
    pieces_free(&r->pieces);
    I2M_CALL(pieces_build(r, &r->pieces));
    r->pieces_valid = true;
  }
  *out = &r->pieces;
  return I2M_OK;
}

void pieces_invalidate(i2m_refine_t *r)
{
  pieces_free(&r->pieces);
  r->pieces_valid = false;
}

void pieces_free(pieces_t *P)
{
  i2m_free(&P->par);
  i2m_free(&P->idx);
  i2m_free(&P->part);
  i2m_free(&P->root);
  i2m_free(&P->comp);
  i2m_free(&P->area);
  i2m_free(&P->face);
  i2m_free(&P->pairs);
  i2m_pieces_global_free(&P->global);
  P->nparts = P->ncomps = P->nareas = P->nfaces = P->npairs = 0;
}

uint32_t pieces_index(const pieces_t *P, uint32_t t) { return atomic_load_explicit(&P->par[t], memory_order_relaxed); }

i2m_err_t i2m_refine_parts(i2m_refine_t *r, i2m_parts_t *out)
{
  pieces_t *P;
  I2M_CALL(pieces_get(r, &P));
  *out = (i2m_parts_t){P->nparts, P->ncomps, P->nareas, P->nfaces, P->part, P->comp, P->area, P->face, P->npairs, P->pairs};
  return I2M_OK;
}

int64_t i2m_refine_part_at_face(i2m_refine_t *r, const i2m_gidx_t key[3], uint16_t label)
{
  const uint32_t f = dist_face_at(r, key);
  if (f == I2M_DT_NONE) return -1;
  const uint32_t t = f >> 2;
  if (!tet_kept(r->dt, t) || tinfo(r->dt, t)->label != label) return -1;
  return pieces_index(&r->pieces, t);
}

/* ---- the pieces of the whole mesh, from every rank's parts ---- */

static int64_t gfind(int64_t *par, int64_t x)
{
  while (par[x] != x) {
    par[x] = par[par[x]];
    x = par[x];
  }
  return x;
}

bool pieces_group_is_fragment(const i2m_refine_t *r, const i2m_group_t *g)
{
  const double voxel_volume = r->img->spacing[0] * r->img->spacing[1] * r->img->spacing[2];
  if (g->ntets > pieces_small_tets(r) || g->comp < 0 || g->volume >= PIECE_FRAGMENT_VOXELS * voxel_volume) return false;
  const int64_t iv = r->pieces_ic.size[g->comp];
  return iv >= PIECE_FRAGMENT_MIN_IMAGE_VOXELS && g->volume * PIECE_FRAGMENT_SHARE < (double)iv * voxel_volume;
}

/* Groups: the union-find over all parts, then each group's sums (parts in order). */
static i2m_err_t make_groups(const i2m_parts_t *all, const int64_t *pairs, size_t npairs, i2m_pieces_global_t *G)
{
  int64_t *par = NULL;
  const size_t n = all->nparts;
  I2M_CALL(i2m_malloc(n ? n : 1, sizeof *par, &par));
  for (size_t i = 0; i < n; i++) par[i] = (int64_t)i;
  for (size_t k = 0; k < npairs; k++) {
    if (pairs[2 * k] < 0 || pairs[2 * k] >= (int64_t)n || pairs[2 * k + 1] < 0 || pairs[2 * k + 1] >= (int64_t)n) {
      i2m_free(&par);
      return I2M_ERROR(I2M_ERR_INTERNAL, "parts %lld and %lld joined, of %zu", (long long)pairs[2 * k], (long long)pairs[2 * k + 1], n);
    }
    const int64_t a = gfind(par, pairs[2 * k]), b = gfind(par, pairs[2 * k + 1]);
    if (a != b) par[a < b ? b : a] = a < b ? a : b;
  }
  G->nparts = n;
  i2m_err_t err = i2m_malloc(n ? n : 1, sizeof *G->part_group, &G->part_group);
  if (err == I2M_OK) err = i2m_calloc(n ? n : 1, sizeof *G->group, &G->group);
  for (size_t i = 0; i < n && err == I2M_OK; i++) { /* groups numbered by their first part */
    if (par[i] == (int64_t)i) { /* a root (roots are the least parts of their groups: their own parent) */
      i2m_group_t *g = &G->group[G->ngroups];
      g->label = all->part[i].label;
      g->comp = -1;
      g->relabel = -1;
      for (int k = 0; k < 4; k++) g->key[k] = g->seed[k] = INT64_MAX;
      par[i] = -1 - (int64_t)G->ngroups++; /* (roots now hold their group) */
    }
  }
  for (size_t i = 0; i < n && err == I2M_OK; i++) {
    int64_t x = (int64_t)i;
    while (par[x] >= 0) x = par[x];
    G->part_group[i] = -1 - par[x];
  }
  for (size_t i = 0; i < n && err == I2M_OK; i++) {
    i2m_group_t *g = &G->group[G->part_group[i]];
    g->ntets += all->part[i].ntets;
    g->volume += all->part[i].volume;
    key_min(g->key, all->part[i].key);
  }
  i2m_free(&par);
  return err;
}

typedef struct {
  int64_t group, comp;
  double volume;
  i2m_gidx_t key[4];
} gcomp_t;

static int cmp_gcomp(const void *a, const void *b)
{
  const gcomp_t *x = a, *y = b;
  if (x->group != y->group) return x->group < y->group ? -1 : 1;
  return (x->comp > y->comp) - (x->comp < y->comp);
}

/* Each group's component: the one that holds the circumcentres of most of its volume (ties:
 * the smaller component), and its least tet there. */
static i2m_err_t group_components(const i2m_parts_t *all, i2m_pieces_global_t *G)
{
  gcomp_t *e = NULL;
  I2M_CALL(i2m_malloc(all->ncomps ? all->ncomps : 1, sizeof *e, &e));
  for (size_t i = 0; i < all->ncomps; i++) {
    const i2m_part_comp_t *c = &all->comp[i];
    e[i] = (gcomp_t){G->part_group[c->part], c->comp, c->volume, {c->key[0], c->key[1], c->key[2], c->key[3]}};
  }
  if (all->ncomps > 1) qsort(e, all->ncomps, sizeof *e, cmp_gcomp);
  for (size_t i = 0, j; i < all->ncomps; i = j) { /* the parts' sums per (group, component) */
    double v = 0;
    i2m_gidx_t k[4] = {INT64_MAX, INT64_MAX, INT64_MAX, INT64_MAX};
    for (j = i; j < all->ncomps && e[j].group == e[i].group && e[j].comp == e[i].comp; j++) {
      v += e[j].volume;
      key_min(k, e[j].key);
    }
    i2m_group_t *g = &G->group[e[i].group];
    if (v > g->comp_volume) {
      g->comp_volume = v;
      g->comp = e[i].comp;
      memcpy(g->seed, k, sizeof k);
    }
  }
  i2m_free(&e);
  return I2M_OK;
}

typedef struct {
  int64_t group;
  uint16_t label;
  double area;
} garea_t;

static int cmp_garea(const void *a, const void *b)
{
  const garea_t *x = a, *y = b;
  if (x->group != y->group) return x->group < y->group ? -1 : 1;
  return (x->label > y->label) - (x->label < y->label);
}

/* Fragments: a small group of a large enough component (pieces_group_is_fragment) that is not
 * the largest small group of a label without a large one takes the label it shares the most
 * face area with (ties: the smaller label index), by the labels before any relabelling. */
static i2m_err_t decide_fragments(const i2m_refine_t *r, const i2m_parts_t *all, i2m_pieces_global_t *G)
{
  const int nl = r->img->nlabels;
  int64_t *main_group = NULL;
  uint8_t *big = NULL;
  garea_t *e = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)nl, sizeof *big, &big));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)nl, sizeof *main_group, &main_group));
  for (int l = 0; l < nl; l++) main_group[l] = -1;
  for (size_t k = 0; k < G->ngroups; k++)
    if (G->group[k].ntets > pieces_small_tets(r)) big[G->group[k].label] = 1;
  for (size_t k = 0; k < G->ngroups; k++) { /* (ties: the least key) */
    const i2m_group_t *g = &G->group[k];
    if (big[g->label]) continue;
    const int64_t m = main_group[g->label];
    if (m < 0 || g->volume > G->group[m].volume ||
        (g->volume == G->group[m].volume && pieces_key_cmp(g->key, G->group[m].key) < 0))
      main_group[g->label] = (int64_t)k;
  }
  I2M_CALL_GOTO(err, done, i2m_malloc(all->nareas ? all->nareas : 1, sizeof *e, &e));
  for (size_t i = 0; i < all->nareas; i++)
    e[i] = (garea_t){G->part_group[all->area[i].part], all->area[i].label, all->area[i].area};
  if (all->nareas > 1) qsort(e, all->nareas, sizeof *e, cmp_garea);
  for (size_t i = 0, j; i < all->nareas; i = j) {
    const int64_t gi = e[i].group;
    i2m_group_t *g = &G->group[gi];
    const bool fragment = main_group[g->label] != gi && pieces_group_is_fragment(r, g);
    double best = -1;
    int best_label = 0;
    for (j = i; j < all->nareas && e[j].group == gi;) {
      size_t k = j;
      double a = 0;
      for (; k < all->nareas && e[k].group == gi && e[k].label == e[j].label; k++) a += e[k].area;
      if (a > best) {
        best = a;
        best_label = e[j].label;
      }
      j = k;
    }
    if (fragment) {
      g->relabel = best_label;
      G->fragments++;
      G->fragment_tets += g->ntets;
    }
  }
done:
  i2m_free(&main_group);
  i2m_free(&big);
  i2m_free(&e);
  return err;
}

/* Groups by component, the largest first (ties: the least key). */
static const i2m_pieces_global_t *sort_G;
static int cmp_by_comp(const void *a, const void *b)
{
  const i2m_group_t *x = &sort_G->group[*(const int64_t *)a], *y = &sort_G->group[*(const int64_t *)b];
  if (x->comp != y->comp) return x->comp < y->comp ? -1 : 1;
  if (x->ntets != y->ntets) return x->ntets > y->ntets ? -1 : 1;
  return pieces_key_cmp(x->key, y->key);
}

/* The components of at least min_voxels that two or more groups (not fragments) stand for. */
static i2m_err_t find_splits(const i2m_refine_t *r, int64_t min_voxels, i2m_pieces_global_t *G)
{
  int64_t *by = NULL;
  size_t n = 0;
  I2M_CALL(i2m_malloc(G->ngroups ? G->ngroups : 1, sizeof *by, &by));
  for (size_t k = 0; k < G->ngroups; k++) {
    const i2m_group_t *g = &G->group[k];
    if (g->comp >= 0 && r->pieces_ic.size[g->comp] >= min_voxels && g->relabel < 0 && !pieces_group_is_fragment(r, g))
      by[n++] = (int64_t)k;
  }
  sort_G = G; /* (qsort has no context argument in C11) */
  if (n > 1) qsort(by, n, sizeof *by, cmp_by_comp);
  i2m_err_t err = I2M_OK;
  for (size_t i = 0, j; i < n && err == I2M_OK; i = j) {
    for (j = i + 1; j < n && G->group[by[j]].comp == G->group[by[i]].comp; j++) {
    }
    if (j - i < 2) continue;
    if (G->nsplits % 16 == 0) err = i2m_realloc(G->nsplits + 16, sizeof *G->split, &G->split);
    if (err != I2M_OK) break;
    i2m_split_t *s = &G->split[G->nsplits++];
    s->comp = G->group[by[i]].comp;
    s->label = G->group[by[i]].label;
    s->ngroups = (uint32_t)(j - i);
    err = i2m_malloc(s->ngroups, sizeof *s->groups, &s->groups);
    for (size_t k = i; k < j && err == I2M_OK; k++) s->groups[k - i] = by[k]; /* (the largest first) */
  }
  i2m_free(&by);
  return err;
}

i2m_err_t i2m_pieces_resolve(const i2m_refine_t *r, const i2m_parts_t *all, const int64_t *pairs, size_t npairs,
                             int64_t min_voxels, i2m_pieces_global_t *G)
{
  memset(G, 0, sizeof *G);
  i2m_err_t err = make_groups(all, pairs, npairs, G);
  if (err == I2M_OK) err = group_components(all, G);
  if (err == I2M_OK) err = decide_fragments(r, all, G);
  if (err == I2M_OK) err = find_splits(r, min_voxels, G);
  if (err != I2M_OK) i2m_pieces_global_free(G);
  return err;
}

void i2m_pieces_global_free(i2m_pieces_global_t *G)
{
  for (size_t i = 0; G->split && i < G->nsplits; i++) i2m_free(&G->split[i].groups);
  i2m_free(&G->split);
  i2m_free(&G->group);
  i2m_free(&G->part_group);
  memset(G, 0, sizeof *G);
}

/* ---- the pieces of the whole mesh in r ---- */

i2m_err_t i2m_refine_groups(i2m_refine_t *r, int64_t min_voxels, const i2m_pieces_global_t **out)
{
  pieces_t *P;
  I2M_CALL(pieces_get(r, &P));
  if (!P->global_valid) { /* (one process: its parts are the whole) */
    I2M_CHECK(!dist_tracking(r), I2M_ERR_INTERNAL, "the pieces of the mesh were not joined across the ranks");
    i2m_parts_t all;
    I2M_CALL(i2m_refine_parts(r, &all));
    I2M_CALL(i2m_pieces_resolve(r, &all, all.pairs, all.npairs, min_voxels, &P->global));
    P->global_valid = true;
  }
  *out = &P->global;
  return I2M_OK;
}

int i2m_refine_groups_valid(const i2m_refine_t *r) { return r->pieces_valid && r->pieces.global_valid; }

i2m_err_t i2m_refine_set_groups(i2m_refine_t *r, i2m_pieces_global_t *G)
{
  pieces_t *P;
  I2M_CALL(pieces_get(r, &P));
  I2M_CHECK(G->nparts == P->nparts, I2M_ERR_INTERNAL, "pieces for %zu parts, %zu here", G->nparts, P->nparts);
  i2m_pieces_global_free(&P->global);
  P->global = *G;
  memset(G, 0, sizeof *G);
  P->global_valid = true;
  return I2M_OK;
}

/* ---- the pieces after the fragments' repair ---- */

/* The fragments' tets that stay in the mesh (their new labels already there): a walk over
 * the faces inside each of their parts, from its least slot (a fragment has at most
 * pieces_small_tets tets: no pass over every tet). */
static i2m_err_t fragment_tets(const i2m_refine_t *r, const uint8_t *moved, uint32_t **out, size_t *n)
{
  const pieces_t *P = &r->pieces;
  const i2m_dt_t *dt = r->dt;
  const size_t most = (size_t)pieces_small_tets(r);
  size_t cap = 0;
  *out = NULL;
  *n = 0;
  for (size_t part = 0; part < P->nparts; part++) {
    if (!moved[part] || !tet_kept(dt, P->root[part])) continue; /* (relabelled 0: out of the mesh) */
    const size_t first = *n;
    if (*n + most + 1 > cap) {
      cap = 2 * cap + most + 256;
      I2M_CALL(i2m_realloc(cap, sizeof **out, out));
    }
    (*out)[(*n)++] = P->root[part];
    for (size_t k = first; k < *n; k++) { /* (the part's tets found so far: a queue) */
      const uint32_t t = (*out)[k];
      for (int i = 0; i < 4; i++) {
        const uint32_t nb = dt->tn[4 * (size_t)t + i];
        if (nb >= I2M_DT_REMOTE || !tet_kept(dt, nb >> 2) || pieces_index(P, nb >> 2) != part) continue;
        bool seen = false;
        for (size_t j = first; j < *n && !seen; j++) seen = (*out)[j] == nb >> 2;
        if (seen) continue;
        I2M_CHECK(*n < cap, I2M_ERR_INTERNAL, "a fragment of more than %zu tets", most);
        (*out)[(*n)++] = nb >> 2;
      }
    }
  }
  return I2M_OK;
}

/* The component entries: a fragment's parts lose theirs (their tets' circumcentres lie in
 * voxels of the old label) and each fragment tet whose circumcentre lies in a component of
 * its new label adds one. */
static i2m_err_t relabel_comps(i2m_refine_t *r, const uint8_t *moved, const uint32_t *ft, size_t nf)
{
  pieces_t *P = &r->pieces;
  size_t n = 0;
  for (size_t i = 0; i < P->ncomps; i++)
    if (!moved[P->comp[i].part]) P->comp[n++] = P->comp[i];
  I2M_CALL(i2m_realloc(n + nf + 1, sizeof *P->comp, &P->comp));
  for (size_t k = 0; k < nf; k++) {
    const uint32_t t = ft[k];
    const int64_t c = tet_component(r, t);
    atomic_store_explicit(&P->idx[t], c < 0 || c >= UINT32_MAX ? UINT32_MAX : (uint32_t)c, memory_order_relaxed);
    if (c < 0) continue;
    i2m_part_comp_t *e = &P->comp[n++];
    *e = (i2m_part_comp_t){{0, 0, 0, 0}, fabs(pieces_tet_volume(r->dt, t)), c, pieces_index(P, t), t};
    pieces_tet_key(r->dt, t, e->key);
  }
  P->ncomps = n;
  return I2M_OK;
}

/* The pairs of parts a fragment tet joins across its faces on this process (a part of its new
 * label on the other side). */
static i2m_err_t relabel_pairs(i2m_refine_t *r, const uint32_t *ft, size_t nf)
{
  pieces_t *P = &r->pieces;
  const i2m_dt_t *dt = r->dt;
  I2M_CALL(i2m_malloc(8 * nf + 1, sizeof *P->pairs, &P->pairs));
  P->npairs = 0;
  for (size_t k = 0; k < nf; k++) {
    const uint32_t t = ft[k], part = pieces_index(P, t);
    const uint16_t l = tinfo(dt, t)->label;
    for (int i = 0; i < 4; i++) {
      const uint32_t nb = dt->tn[4 * (size_t)t + i];
      if (nb >= I2M_DT_REMOTE || !tet_kept(dt, nb >> 2) || tinfo(dt, nb >> 2)->label != l) continue;
      const uint32_t other = pieces_index(P, nb >> 2);
      if (other == part) continue;
      P->pairs[2 * P->npairs] = part;
      P->pairs[2 * P->npairs + 1] = other;
      P->npairs++;
    }
  }
  return I2M_OK;
}

/* The relabelled mesh's parts are the parts before, joined: a fragment keeps its tets and
 * only gains neighbours.  So its pieces follow from the parts before and a scan of the
 * fragments' tets: each fragment part takes its new label (label 0: it left the mesh, and
 * counts nowhere), new component entries and the pairs it makes, on this process; its faces
 * to other ranks carry its new label, and the dist layer pairs them as before.  The same
 * groups, labels, tets and components as a pass over every tet would find (1.4-2.1 s on the
 * knee at 6 M tets).  No areas: a second round of fragments is not wanted, and a group that
 * would be one is left out of the splits anyway (pieces_group_is_fragment). */
i2m_err_t pieces_after_relabel(i2m_refine_t *r)
{
  pieces_t *P = &r->pieces;
  I2M_CHECK(r->pieces_valid && P->global_valid, I2M_ERR_INTERNAL, "the pieces before the fragments' repair are gone");
  const i2m_pieces_global_t *G = &P->global;
  uint32_t *ft = NULL;
  size_t nf = 0;
  uint8_t *moved = NULL;
  i2m_err_t err = i2m_calloc(P->nparts + 1, sizeof *moved, &moved);
  for (size_t i = 0; err == I2M_OK && i < P->nparts; i++) {
    const int32_t to = G->group[G->part_group[i]].relabel;
    if (to < 0) continue;
    moved[i] = 1;
    P->part[i].label = (uint16_t)to;
  }
  if (err == I2M_OK) err = fragment_tets(r, moved, &ft, &nf);
  for (size_t k = 0; err == I2M_OK && k < P->nfaces; k++)
    if (moved[P->face[k].part]) P->face[k].label = P->part[P->face[k].part].label;
  if (err == I2M_OK) err = relabel_comps(r, moved, ft, nf);
  if (err == I2M_OK) err = relabel_pairs(r, ft, nf);
  P->nareas = 0;
  i2m_free(&ft);
  i2m_free(&moved);
  i2m_pieces_global_free(&P->global);
  P->global_valid = false;
  if (err != I2M_OK) pieces_invalidate(r);
  return err;
}

/* ---- the census per label ---- */

i2m_err_t i2m_refine_census_of(i2m_refine_t *r, const i2m_pieces_global_t *G, int64_t min_voxels,
                               i2m_label_pieces_t **out)
{
  const int nl = r->img->nlabels;
  i2m_label_pieces_t *L = NULL;
  if (!r->pieces_ic.nruns) I2M_CALL(i2m_edt_components(r->edt, &r->pieces_ic));
  I2M_CALL(i2m_calloc((size_t)nl, sizeof *L, &L));
  for (int l = 0; l < nl; l++) L[l].value = r->img->label_value[l];
  const i2m_components_t *ic = &r->pieces_ic;
  for (int64_t k = 0; k < ic->nruns; k++) {
    if (ic->par[k] != k || ic->lab[k] == 0) continue;
    L[ic->lab[k]].image_components++;
    L[ic->lab[k]].large_components += ic->size[k] >= min_voxels;
  }
  for (size_t i = 0; i < G->ngroups; i++) /* (label 0: fragments that left the mesh, see pieces_after_relabel) */
    if (G->group[i].label) L[G->group[i].label].mesh_pieces++;
  for (size_t i = 0; i < G->nsplits; i++) L[G->split[i].label].split_components++;
  *out = L;
  return I2M_OK;
}

i2m_err_t i2m_refine_census(i2m_refine_t *r, int64_t min_voxels, i2m_label_pieces_t **out)
{
  const i2m_pieces_global_t *G = NULL;
  *out = NULL;
  I2M_CALL(i2m_refine_groups(r, min_voxels, &G));
  return i2m_refine_census_of(r, G, min_voxels, out);
}
