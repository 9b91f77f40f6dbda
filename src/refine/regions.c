/* Refine layer: does a local change keep the tissues' connections?  (The sliver pass.)
 *
 * A change (an insertion, a vertex moved) replaces the tets of a region by others that fill
 * the same region, labelled anew from their circumcentres.  Through a thin neck of a tissue
 * the new labels can cut the only path of that tissue's tets: on the knee at delta 0.8,
 * `--sliver-angle 15` left labels 41 and 46 in 2 and 3 pieces although the component rule
 * had joined them, and head_colin27 one label in 2.  So a change is kept only when, for every
 * label, the tets of that label just outside the region that were joined through the
 * region's tets of that label (across faces) are still joined through the new ones, and it
 * leaves no more pieces that touch nothing of their label outside.  Paths outside the region
 * are not looked at: the test is local and conservative, and the decision depends on the
 * region and its neighbours only (the same with any number of threads or ranks).
 *
 * A region is summed up, while its tets are alive, by its pieces (its tets of one label other
 * than 0, joined across its inner faces) and its ports: the boundary faces whose tet and whose
 * neighbour across carry the same label, each with its piece and the face's vertex slots (the
 * boundary is the same before and after a change: the ports are matched by those slots). */
#include "refine_impl.h"

#include <string.h>

#define NOT_FOUND UINT32_MAX
#define HOLE (UINT32_MAX - 1)

/* ---- a set of tet slots with an index each (open addressing, cleared by a stamp) ---- */

/* An empty table of at least 4 n slots (a power of two) whose entry h is current when
 * stamp[h] is *now: the stamps, and the arrays a and b (NULL: none) beside them, grown as
 * needed; a new stamp empties it. */
static i2m_err_t stamped_empty(uint32_t n, uint32_t *cap, uint32_t *now, uint32_t **stamp, uint32_t **a, uint32_t **b)
{
  if (4 * n > *cap) {
    uint32_t c = *cap ? *cap : 256;
    while (c < 4 * n) c *= 2;
    I2M_CALL(i2m_realloc(c, sizeof **a, a));
    if (b) I2M_CALL(i2m_realloc(c, sizeof **b, b));
    I2M_CALL(i2m_realloc(c, sizeof **stamp, stamp));
    memset(*stamp, 0, c * sizeof **stamp);
    *cap = c;
    *now = 0;
  }
  if (++*now == 0) { /* (wrapped: every entry would look current) */
    memset(*stamp, 0, *cap * sizeof **stamp);
    *now = 1;
  }
  return I2M_OK;
}

static i2m_err_t index_clear(region_scratch_t *S, uint32_t n)
{
  return stamped_empty(n, &S->cap, &S->stamp, &S->stamp_of, &S->key, &S->val);
}

static void index_put(region_scratch_t *S, uint32_t t, uint32_t i)
{
  const uint32_t mask = S->cap - 1;
  uint32_t h = (t * 0x9E3779B1u) >> 7 & mask;
  while (S->stamp_of[h] == S->stamp && S->key[h] != t) h = (h + 1) & mask;
  S->stamp_of[h] = S->stamp;
  S->key[h] = t;
  S->val[h] = i;
}

static uint32_t index_get(const region_scratch_t *S, uint32_t t)
{
  const uint32_t mask = S->cap - 1;
  for (uint32_t h = (t * 0x9E3779B1u) >> 7 & mask; S->stamp_of[h] == S->stamp; h = (h + 1) & mask)
    if (S->key[h] == t) return S->val[h];
  return NOT_FOUND;
}

/* ---- pieces ---- */

static i2m_err_t parents_fit(region_scratch_t *S, uint32_t n)
{
  if (n <= S->cap_parent) return I2M_OK;
  S->cap_parent = n + n / 2 + 64;
  return i2m_realloc(S->cap_parent, sizeof *S->parent, &S->parent);
}

static uint32_t root_of(uint32_t *parent, uint32_t x)
{
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

static void join(uint32_t *parent, uint32_t a, uint32_t b)
{
  a = root_of(parent, a);
  b = root_of(parent, b);
  if (a != b) parent[a < b ? b : a] = a < b ? a : b;
}

/* The sorted vertex slots of face j of tet t. */
static void face_key(const i2m_dt_t *dt, uint32_t t, int j, uint32_t k[3])
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  uint32_t a = v[(j + 1) & 3], b = v[(j + 2) & 3], c = v[(j + 3) & 3], s;
  if (a > b) s = a, a = b, b = s;
  if (b > c) s = b, b = c, c = s;
  if (a > b) s = a, a = b, b = s;
  k[0] = a;
  k[1] = b;
  k[2] = c;
}

static i2m_err_t port_push(region_t *R, const uint32_t k[3], uint32_t node, uint32_t across)
{
  if (R->nport == R->cap_port) {
    R->cap_port = R->cap_port ? 2 * R->cap_port : 64;
    I2M_CALL(i2m_realloc(R->cap_port, sizeof *R->port, &R->port));
  }
  R->port[R->nport++] = (region_port_t){{k[0], k[1], k[2]}, node, across, false};
  return I2M_OK;
}

/* The ports' nodes become their pieces (roots), each piece's ports are counted, and the
 * pieces of nodes 0..n (those of a label other than 0: `labelled`) that have none are
 * counted as portless. */
static i2m_err_t settle(region_scratch_t *S, region_t *R, uint32_t n, const bool *labelled)
{
  if (n > S->cap_count) {
    S->cap_count = n + n / 2 + 64;
    I2M_CALL(i2m_realloc(S->cap_count, sizeof *S->count, &S->count));
  }
  memset(S->count, 0, n * sizeof *S->count);
  for (uint32_t p = 0; p < R->nport; p++) {
    R->port[p].piece = root_of(S->parent, R->port[p].piece);
    S->count[R->port[p].piece]++;
  }
  for (uint32_t p = 0; p < R->nport; p++) R->port[p].shared = S->count[R->port[p].piece] > 1;
  R->portless = 0;
  for (uint32_t i = 0; i < n; i++)
    if (labelled[i] && root_of(S->parent, i) == i && S->count[i] == 0) R->portless++;
  return I2M_OK;
}

static i2m_err_t labelled_fit(region_scratch_t *S, uint32_t n)
{
  if (n <= S->cap_labelled) return I2M_OK;
  S->cap_labelled = n + n / 2 + 64;
  I2M_CALL(i2m_realloc(S->cap_labelled, sizeof *S->label, &S->label));
  return i2m_realloc(S->cap_labelled, sizeof *S->labelled, &S->labelled);
}

int region_uniform_label(const i2m_dt_t *dt, const uint32_t *tets, uint32_t n)
{
  const int l = n ? tinfo(dt, tets[0])->label : -1;
  for (uint32_t i = 1; i < n; i++)
    if (tinfo(dt, tets[i])->label != l) return -1;
  return l;
}

i2m_err_t region_of_tets(region_scratch_t *S, const i2m_dt_t *dt, const uint32_t *tets, uint32_t n, int as_label,
                         region_t *R)
{
  R->nport = 0;
  R->nnodes = n;
  I2M_CALL(index_clear(S, n));
  I2M_CALL(parents_fit(S, n));
  I2M_CALL(labelled_fit(S, n));
  for (uint32_t i = 0; i < n; i++) {
    index_put(S, tets[i], i);
    S->parent[i] = i;
    S->label[i] = (uint16_t)(as_label >= 0 ? as_label : tinfo(dt, tets[i])->label);
    S->labelled[i] = S->label[i] != 0;
  }
  for (uint32_t i = 0; i < n; i++) {
    const uint32_t t = tets[i], label = S->label[i];
    if (label == 0) continue;
    for (int j = 0; j < 4; j++) {
      const uint32_t nb = dt->tn[4 * (size_t)t + j];
      if (nb >= I2M_DT_REMOTE) continue; /* (the hull: outside) */
      const uint32_t o = index_get(S, nb >> 2);
      if (o != NOT_FOUND) {
        if (S->label[o] == label) join(S->parent, i, o);
      } else if (tinfo(dt, nb >> 2)->label == label) {
        uint32_t k[3];
        face_key(dt, t, j, k);
        I2M_CALL(port_push(R, k, i, nb >> 2));
      }
    }
  }
  return settle(S, R, n, S->labelled);
}

i2m_err_t region_grow(region_scratch_t *S, const i2m_dt_t *dt, const region_t *R, const uint32_t *extra, uint32_t n,
                      const uint32_t *hole, uint32_t nhole, region_t *out)
{
  const uint32_t base = R->nnodes, nodes = base + n;
  out->nport = 0;
  out->nnodes = nodes;
  I2M_CALL(index_clear(S, n + nhole));
  I2M_CALL(parents_fit(S, nodes));
  I2M_CALL(labelled_fit(S, nodes));
  for (uint32_t i = 0; i < nodes; i++) S->parent[i] = i;
  memset(S->labelled, 0, base * sizeof *S->labelled);
  for (uint32_t p = 0; p < R->nport; p++) S->labelled[R->port[p].piece] = true; /* (R's pieces with ports) */
  for (uint32_t i = 0; i < nhole; i++) index_put(S, hole[i], HOLE);
  for (uint32_t i = 0; i < n; i++) {
    index_put(S, extra[i], base + i);
    S->labelled[base + i] = tinfo(dt, extra[i])->label != 0;
  }
  /* R's ports into the new tets join them (same label on both sides); the others stay */
  for (uint32_t p = 0; p < R->nport; p++) {
    const uint32_t o = index_get(S, R->port[p].across);
    if (o != NOT_FOUND && o != HOLE) join(S->parent, R->port[p].piece, o);
    else I2M_CALL(port_push(out, R->port[p].k, R->port[p].piece, R->port[p].across));
  }
  for (uint32_t i = 0; i < n; i++) {
    const uint32_t t = extra[i], label = tinfo(dt, t)->label;
    if (label == 0) continue;
    for (int j = 0; j < 4; j++) {
      const uint32_t nb = dt->tn[4 * (size_t)t + j];
      if (nb >= I2M_DT_REMOTE || tinfo(dt, nb >> 2)->label != label) continue;
      const uint32_t o = index_get(S, nb >> 2);
      if (o == HOLE) continue; /* (a face of R's boundary: joined from R's side above) */
      if (o != NOT_FOUND) {
        join(S->parent, base + i, o);
      } else {
        uint32_t k[3];
        face_key(dt, t, j, k);
        I2M_CALL(port_push(out, k, base + i, nb >> 2));
      }
    }
  }
  /* R's portless pieces stay portless unless a new tet joined them */
  I2M_CALL(settle(S, out, nodes, S->labelled));
  out->portless += R->portless;
  return I2M_OK;
}

static bool same_key(const uint32_t a[3], const uint32_t b[3]) { return a[0] == b[0] && a[1] == b[1] && a[2] == b[2]; }

static uint32_t key_hash(const uint32_t k[3])
{
  return (k[0] * 0x9E3779B1u ^ k[1] * 0x85EBCA77u ^ k[2] * 0xC2B2AE3Du) >> 7;
}

/* After's ports by their keys (open addressing, cleared by a stamp). */
static i2m_err_t ports_index(region_scratch_t *S, const region_t *after)
{
  I2M_CALL(stamped_empty(after->nport, &S->cap_pk, &S->pk_stamp, &S->port_stamp, &S->port_at, NULL));
  S->port_key = after->port; /* (borrowed: the keys stay in after's ports) */
  const uint32_t mask = S->cap_pk - 1;
  for (uint32_t q = 0; q < after->nport; q++) {
    uint32_t h = key_hash(after->port[q].k) & mask;
    while (S->port_stamp[h] == S->pk_stamp) h = (h + 1) & mask;
    S->port_stamp[h] = S->pk_stamp;
    S->port_at[h] = q;
  }
  return I2M_OK;
}

/* The piece after of the port with key k, or NOT_FOUND when no port after has it. */
static uint32_t piece_after(const region_scratch_t *S, const uint32_t k[3])
{
  const uint32_t mask = S->cap_pk - 1;
  for (uint32_t h = key_hash(k) & mask; S->port_stamp[h] == S->pk_stamp; h = (h + 1) & mask) {
    const region_port_t *a = &S->port_key[S->port_at[h]];
    if (same_key(a->k, k)) return a->piece;
  }
  return NOT_FOUND;
}

static bool across_readable(const region_scratch_t *S, uint32_t t, int j)
{
  return !S->readable || S->readable(S->readable_arg, t, j);
}

/* After's pieces joined through the tets just outside: two pieces with ports into the same
 * tet, or into two tets of their label that share a face, are one (S->parent over after's
 * nodes; S's tet index maps each tet across a port to a piece). */
static i2m_err_t join_outside(region_scratch_t *S, const i2m_dt_t *dt, const region_t *after)
{
  I2M_CALL(parents_fit(S, after->nnodes));
  for (uint32_t i = 0; i < after->nnodes; i++) S->parent[i] = i;
  I2M_CALL(index_clear(S, after->nport + 1));
  for (uint32_t q = 0; q < after->nport; q++) {
    const region_port_t *a = &after->port[q];
    const uint32_t o = index_get(S, a->across);
    if (o == NOT_FOUND) index_put(S, a->across, a->piece);
    else join(S->parent, a->piece, o);
  }
  for (uint32_t q = 0; q < after->nport; q++) {
    const region_port_t *a = &after->port[q];
    const int label = tinfo(dt, a->across)->label;
    for (int j = 0; j < 4; j++) {
      if (!across_readable(S, a->across, j)) continue;
      const uint32_t nb = dt->tn[4 * (size_t)a->across + j];
      if (nb >= I2M_DT_REMOTE) continue;
      const uint32_t o = index_get(S, nb >> 2);
      if (o != NOT_FOUND && tinfo(dt, nb >> 2)->label == label) join(S->parent, a->piece, o);
    }
  }
  return I2M_OK;
}

/* The piece after (joined through the outside) that before's port b reaches: by its face when
 * that is a port after, else through the tet across it, or a tet of its label next to that
 * one, when either has a port after; NOT_FOUND when none. */
static uint32_t reached_after(region_scratch_t *S, const i2m_dt_t *dt, const region_port_t *b)
{
  uint32_t p = piece_after(S, b->k);
  if (!dt) return p;
  if (p == NOT_FOUND) p = index_get(S, b->across);
  for (int j = 0; j < 4 && p == NOT_FOUND; j++) {
    if (!across_readable(S, b->across, j)) continue;
    const uint32_t nb = dt->tn[4 * (size_t)b->across + j];
    if (nb < I2M_DT_REMOTE && tinfo(dt, nb >> 2)->label == tinfo(dt, b->across)->label) p = index_get(S, nb >> 2);
  }
  return p == NOT_FOUND ? p : root_of(S->parent, p);
}

i2m_err_t region_keeps(region_scratch_t *S, const i2m_dt_t *dt, const region_t *before, const region_t *after,
                       bool *keeps)
{
  S->nfailed = 0;
  *keeps = after->portless <= before->portless;
  if (!*keeps) return I2M_OK;
  /* every piece before with two ports or more: its ports all reach one piece after (else the
   * piece is listed: the caller may find its ports joined farther out) */
  if (before->nnodes > S->cap_count) {
    S->cap_count = before->nnodes + before->nnodes / 2 + 64;
    I2M_CALL(i2m_realloc(S->cap_count, sizeof *S->count, &S->count));
  }
  I2M_CALL(ports_index(S, after));
  if (dt) I2M_CALL(join_outside(S, dt, after));
  for (uint32_t p = 0; p < before->nport; p++) S->count[before->port[p].piece] = NOT_FOUND;
  for (uint32_t p = 0; p < before->nport; p++) {
    const region_port_t *b = &before->port[p];
    uint32_t *first = &S->count[b->piece];
    if (!b->shared || *first == HOLE) continue; /* (HOLE: the piece is listed already) */
    const uint32_t now = reached_after(S, dt, b);
    if (now != NOT_FOUND && (*first == NOT_FOUND || *first == now)) {
      *first = now;
      continue;
    }
    *first = HOLE;
    if (S->nfailed == S->cap_failed) {
      S->cap_failed = S->cap_failed ? 2 * S->cap_failed : 16;
      I2M_CALL(i2m_realloc(S->cap_failed, sizeof *S->failed, &S->failed));
    }
    S->failed[S->nfailed++] = b->piece;
  }
  *keeps = S->nfailed == 0;
  return I2M_OK;
}

void region_free(region_t *R)
{
  i2m_free(&R->port);
  memset(R, 0, sizeof *R);
}

void region_scratch_free(region_scratch_t *S)
{
  i2m_free(&S->key);
  i2m_free(&S->val);
  i2m_free(&S->stamp_of);
  i2m_free(&S->parent);
  i2m_free(&S->count);
  i2m_free(&S->labelled);
  i2m_free(&S->label);
  i2m_free(&S->port_stamp);
  i2m_free(&S->port_at);
  i2m_free(&S->failed);
  memset(S, 0, sizeof *S);
}
