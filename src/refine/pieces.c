/* Refine layer: the pieces of the labelled mesh and the image components they stand for.
 *
 * A piece is a face-connected set of kept tets of one label.  Pieces come from a union-find
 * over the tet slots, in parallel (compare-and-swap links, always from the larger root to the
 * smaller, so every piece ends with its smallest slot as root whatever the threads did).
 *
 * Each piece stands for the 6-connected image component (of its label) that holds the
 * circumcentre of its first tet whose circumcentre lies in a voxel of its label: a tet's
 * label is the label of the voxel that holds its circumcentre, so nearly always the root's.
 * The census counts, per label, the image's components, the mesh's pieces, and the large
 * components (at least min_voxels voxels) that the mesh splits: two or more pieces that are
 * not fragments (fragments.c relabels those) stand for one component.  fragments.c and
 * bridges.c build on it. */
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

/* par[t] = the smallest slot of t's piece; the number of tets of each piece at its root in
 * cnt (saturating at PIECE_SMALL_TETS + 1). */
static void find_pieces(const i2m_dt_t *dt, _Atomic uint32_t *par, _Atomic uint32_t *cnt)
{
  const int64_t n = i2m_dt_ntets_slots(dt);
  I2M_OMP(omp parallel)
  {
    I2M_OMP(omp for schedule(static))
    for (int64_t t = 0; t < n; t++) {
      atomic_init(&par[t], (uint32_t)t);
      atomic_init(&cnt[t], 0);
    }
    I2M_OMP(omp for schedule(dynamic, 4096))
    for (int64_t t = 0; t < n; t++) {
      if (!tet_kept(dt, (uint32_t)t)) continue;
      const uint16_t l = tinfo(dt, (uint32_t)t)->label;
      for (int i = 0; i < 4; i++) {
        uint32_t nb = dt->tn[4 * (size_t)t + i];
        if (nb >= I2M_DT_REMOTE || (nb >> 2) > (uint32_t)t) continue; /* each face once */
        if (tinfo(dt, nb >> 2)->label == l) uf_union(par, (uint32_t)t, nb >> 2); /* (a neighbour is alive) */
      }
    }
    I2M_OMP(omp for schedule(static))
    for (int64_t t = 0; t < n; t++) {
      if (!tet_kept(dt, (uint32_t)t)) continue;
      const uint32_t root = uf_find(par, (uint32_t)t);
      atomic_store_explicit(&par[t], root, memory_order_relaxed); /* (an ancestor: finds stay right) */
      if (atomic_load_explicit(&cnt[root], memory_order_relaxed) <= PIECE_SMALL_TETS)
        atomic_fetch_add_explicit(&cnt[root], 1, memory_order_relaxed);
    }
  }
}

double pieces_tet_volume(const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  return i2m_tet_signed_volume6(i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]),
                                i2m_dt_xyz(dt, v[3])) / 6.0;
}

static int cmp_u64(const void *a, const void *b)
{
  const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
  return (x > y) - (x < y);
}

/* The tets of small pieces as (root << 32 | slot), sorted (grouped by piece, in slot order). */
static i2m_err_t small_piece_tets(const i2m_dt_t *dt, pieces_t *P)
{
  const uint32_t n = i2m_dt_ntets_slots(dt);
  size_t cap = 0;
  for (uint32_t t = 0; t < n; t++) {
    if (!tet_kept(dt, t)) continue;
    const uint32_t root = atomic_load_explicit(&P->par[t], memory_order_relaxed);
    if (atomic_load_explicit(&P->cnt[root], memory_order_relaxed) > PIECE_SMALL_TETS) continue;
    if (P->nsmall == cap) {
      cap = 2 * cap + 256;
      I2M_CALL(i2m_realloc(cap, sizeof *P->small, &P->small));
    }
    P->small[P->nsmall++] = (uint64_t)root << 32 | t;
  }
  if (P->nsmall > 1) qsort(P->small, P->nsmall, sizeof *P->small, cmp_u64);
  return I2M_OK;
}

/* The image component of voxel-frame point u if its voxel has label index lab, else -1. */
static int64_t component_at(const i2m_refine_t *r, const double u[3], int lab)
{
  int64_t v[3];
  if (!i2m_edt_image_voxel_k(r->edt, u, v) || i2m_edt_label_voxel(r->edt, v[0], v[1], v[2]) != lab) return -1;
  return i2m_components_find(&r->pieces_ic, v[0], v[1], v[2]);
}

/* The component tet t stands for: that of its circumcentre, if it lies in its label (-1). */
static int64_t tet_component(const i2m_refine_t *r, uint32_t t)
{
  tet_geom_t g;
  tet_centre(r, t, &g); /* (a flat tet's u is NaN: no voxel) */
  return component_at(r, g.u, tinfo(r->dt, t)->label);
}

/* The piece table (roots in slot order, so sorted by root); then par[t] becomes t's piece
 * index and cnt[t] its component (UINT32_MAX: none), in parallel. */
static i2m_err_t list_pieces(const i2m_refine_t *r, pieces_t *P)
{
  const i2m_dt_t *dt = r->dt;
  const uint32_t n = i2m_dt_ntets_slots(dt);
  size_t cap = 0;
  for (uint32_t t = 0; t < n; t++) {
    if (!tet_kept(dt, t) || atomic_load_explicit(&P->par[t], memory_order_relaxed) != t) continue;
    if (P->npieces == cap) {
      cap = 2 * cap + 256;
      I2M_CALL(i2m_realloc(cap, sizeof *P->piece, &P->piece));
    }
    const bool small = atomic_load_explicit(&P->cnt[t], memory_order_relaxed) <= PIECE_SMALL_TETS;
    atomic_store_explicit(&P->cnt[t], (uint32_t)P->npieces, memory_order_relaxed); /* (the root's index, for now) */
    P->piece[P->npieces++] = (piece_t){t, tinfo(dt, t)->label, small, 0, 0, 0.0, -1};
  }
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t t = 0; t < (int64_t)n; t++) { /* every tet's piece index, from its root */
    if (!tet_kept(dt, (uint32_t)t)) continue;
    const uint32_t root = atomic_load_explicit(&P->par[t], memory_order_relaxed);
    atomic_store_explicit(&P->par[t], atomic_load_explicit(&P->cnt[root], memory_order_relaxed), memory_order_relaxed);
  }
  return I2M_OK;
}

/* Tet t's component, into cnt[t] (which then holds it: tet_comp). */
static uint32_t note_comp(const i2m_refine_t *r, pieces_t *P, uint32_t t)
{
  const int64_t c = tet_component(r, t);
  const uint32_t x = c < 0 || c >= UINT32_MAX ? UINT32_MAX : (uint32_t)c;
  atomic_store_explicit(&P->cnt[t], x, memory_order_relaxed);
  return x;
}

static uint32_t tet_comp(const pieces_t *P, uint32_t t) { return atomic_load_explicit(&P->cnt[t], memory_order_relaxed); }

/* Small pieces: their tets, volume, and the component that holds the circumcentres of the
 * largest volume of their tets (ties: the first). */
static void describe_small(const i2m_refine_t *r, pieces_t *P)
{
  const i2m_dt_t *dt = r->dt;
  size_t k = 0;
  while (k < P->nsmall) {
    const uint32_t t0 = (uint32_t)P->small[k];
    piece_t *p = &P->piece[pieces_index(P, t0)];
    p->start = (uint32_t)k;
    for (; k < P->nsmall && pieces_index(P, (uint32_t)P->small[k]) == pieces_index(P, t0); k++) {
      p->n++;
      p->volume += pieces_tet_volume(dt, (uint32_t)P->small[k]);
      note_comp(r, P, (uint32_t)P->small[k]);
    }
    double best = 0;
    for (uint32_t i = 0; i < p->n; i++) {
      const uint32_t c = tet_comp(P, (uint32_t)P->small[p->start + i]);
      double w = 0;
      for (uint32_t j = 0; j < p->n && c != UINT32_MAX; j++) {
        const uint32_t u = (uint32_t)P->small[p->start + j];
        if (tet_comp(P, u) == c) w += fabs(pieces_tet_volume(dt, u));
      }
      if (c != UINT32_MAX && w > best) {
        best = w;
        p->comp = c;
      }
    }
  }
}

/* Large pieces: the component that holds the circumcentres of most of the volume of their
 * first PIECE_SAMPLE tets (in slot order), by a weighted majority vote in one pass (Boyer and
 * Moore's: exact whenever one component holds more than half of it, as it does for every
 * large piece: a large piece of one label lies in one component of that label). */
#define PIECE_SAMPLE 256
static i2m_err_t describe_large(const i2m_refine_t *r, pieces_t *P)
{
  const i2m_dt_t *dt = r->dt;
  double *w = NULL;
  uint32_t *seen = NULL;
  I2M_CALL(i2m_calloc(P->npieces ? P->npieces : 1, sizeof *w, &w));
  i2m_err_t err = i2m_calloc(P->npieces ? P->npieces : 1, sizeof *seen, &seen);
  const uint32_t n = i2m_dt_ntets_slots(dt);
  for (uint32_t t = 0; t < n && err == I2M_OK; t++) {
    if (!tet_kept(dt, t)) continue;
    const uint32_t pi = pieces_index(P, t);
    piece_t *p = &P->piece[pi];
    if (p->small || seen[pi] >= PIECE_SAMPLE) {
      atomic_store_explicit(&P->cnt[t], UINT32_MAX, memory_order_relaxed); /* (not looked at) */
      continue;
    }
    seen[pi]++;
    const uint32_t c = note_comp(r, P, t);
    if (c == UINT32_MAX) continue;
    const double v = fabs(pieces_tet_volume(dt, t));
    if (p->comp == (int64_t)c) w[pi] += v;
    else if (w[pi] >= v) w[pi] -= v;
    else {
      p->comp = c;
      w[pi] = v - w[pi];
    }
  }
  i2m_free(&w);
  i2m_free(&seen);
  return err;
}

i2m_err_t pieces_get(i2m_refine_t *r, const pieces_t **out)
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

i2m_err_t pieces_build(i2m_refine_t *r, pieces_t *P)
{
  const i2m_dt_t *dt = r->dt;
  const uint32_t n = i2m_dt_ntets_slots(dt);
  memset(P, 0, sizeof *P);
  if (!r->pieces_ic.nruns) I2M_CALL(i2m_edt_components(r->edt, &r->pieces_ic));
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, fail, i2m_malloc(n ? n : 1, sizeof *P->par, &P->par));
  I2M_CALL_GOTO(err, fail, i2m_malloc(n ? n : 1, sizeof *P->cnt, &P->cnt));
  find_pieces(dt, P->par, P->cnt);
  I2M_CALL_GOTO(err, fail, small_piece_tets(dt, P));
  I2M_CALL_GOTO(err, fail, list_pieces(r, P));
  describe_small(r, P);
  I2M_CALL_GOTO(err, fail, describe_large(r, P));
  return I2M_OK;
fail:
  pieces_free(P);
  return err;
}

void pieces_free(pieces_t *P)
{
  i2m_free(&P->par);
  i2m_free(&P->cnt);
  i2m_free(&P->small);
  i2m_free(&P->piece);
  P->npieces = P->nsmall = 0;
}

uint32_t pieces_index(const pieces_t *P, uint32_t t) { return atomic_load_explicit(&P->par[t], memory_order_relaxed); }

bool pieces_is_fragment(const i2m_refine_t *r, const piece_t *p)
{
  const double voxel_volume = r->img->spacing[0] * r->img->spacing[1] * r->img->spacing[2];
  if (!p->small || p->comp < 0 || p->volume >= PIECE_FRAGMENT_VOXELS * voxel_volume) return false;
  const int64_t iv = r->pieces_ic.size[p->comp];
  return iv >= PIECE_FRAGMENT_MIN_IMAGE_VOXELS && p->volume * PIECE_FRAGMENT_SHARE < (double)iv * voxel_volume;
}

static int cmp_piece_comp(const void *a, const void *b)
{
  const piece_t *x = *(const piece_t *const *)a, *y = *(const piece_t *const *)b;
  if (x->comp != y->comp) return x->comp < y->comp ? -1 : 1;
  return (x->root > y->root) - (x->root < y->root);
}

i2m_err_t pieces_splits(const i2m_refine_t *r, const pieces_t *P, int64_t min_voxels, split_t **out, size_t *nout)
{
  piece_t **by = NULL;
  split_t *sp = NULL;
  size_t n = 0, ns = 0;
  *out = NULL;
  *nout = 0;
  if (P->npieces == 0) return I2M_OK;
  I2M_CALL(i2m_malloc(P->npieces, sizeof *by, &by));
  for (size_t i = 0; i < P->npieces; i++) { /* the pieces that are not fragments, of large components */
    piece_t *p = &P->piece[i];
    if (p->comp >= 0 && r->pieces_ic.size[p->comp] >= min_voxels && !pieces_is_fragment(r, p)) by[n++] = p;
  }
  qsort(by, n, sizeof *by, cmp_piece_comp);
  i2m_err_t err = I2M_OK;
  for (size_t i = 0, j; i < n; i = j) {
    for (j = i + 1; j < n && by[j]->comp == by[i]->comp; j++) {
    }
    if (j - i < 2) continue;
    if (ns % 16 == 0) I2M_CALL_GOTO(err, done, i2m_realloc(ns + 16, sizeof *sp, &sp));
    split_t *s = &sp[ns++];
    memset(s, 0, sizeof *s);
    s->comp = by[i]->comp;
    s->label = by[i]->label;
    s->npieces = (uint32_t)(j - i);
    I2M_CALL_GOTO(err, done, i2m_malloc(s->npieces, sizeof *s->pieces, &s->pieces));
    for (size_t k = i; k < j; k++) s->pieces[k - i] = (uint32_t)(by[k] - P->piece);
  }
  *out = sp;
  *nout = ns;
  sp = NULL;
done:
  splits_free(&sp, ns);
  i2m_free(&by);
  return err;
}

void splits_free(split_t **s, size_t n)
{
  for (size_t i = 0; *s && i < n; i++) i2m_free(&(*s)[i].pieces);
  i2m_free(s);
}

i2m_err_t i2m_refine_census(i2m_refine_t *r, int64_t min_voxels, i2m_label_pieces_t **out)
{
  const int nl = r->img->nlabels;
  i2m_label_pieces_t *L = NULL;
  const pieces_t *P;
  split_t *sp = NULL;
  size_t ns = 0;
  *out = NULL;
  I2M_CALL(pieces_get(r, &P));
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)nl, sizeof *L, &L));
  for (int l = 0; l < nl; l++) L[l].value = r->img->label_value[l];
  const i2m_components_t *ic = &r->pieces_ic;
  for (int64_t k = 0; k < ic->nruns; k++) {
    if (ic->par[k] != k || ic->lab[k] == 0) continue;
    L[ic->lab[k]].image_components++;
    L[ic->lab[k]].large_components += ic->size[k] >= min_voxels;
  }
  for (size_t i = 0; i < P->npieces; i++) L[P->piece[i].label].mesh_pieces++;
  I2M_CALL_GOTO(err, done, pieces_splits(r, P, min_voxels, &sp, &ns));
  for (size_t i = 0; i < ns; i++) {
    L[sp[i].label].split_components++;
    if (i2m_log_get_level() >= I2M_LOG_DEBUG)
      for (uint32_t k = 0; k < sp[i].npieces; k++) {
        const piece_t *p = &P->piece[sp[i].pieces[k]];
        double c[3] = {0, 0, 0};
        for (int j = 0; j < 4; j++)
          for (int a = 0; a < 3; a++) c[a] += 0.25 * i2m_dt_xyz(r->dt, r->dt->tv[4 * (size_t)p->root + j])[a];
        i2m_debug("census: label %lld component of %lld voxels: piece %u: %s, volume %g, at (%g, %g, %g)",
                  (long long)L[sp[i].label].value, (long long)r->pieces_ic.size[sp[i].comp], k, p->small ? "small" : "large",
                  p->volume, c[0], c[1], c[2]);
      }
  }
  *out = L;
  L = NULL;
done:
  splits_free(&sp, ns);
  i2m_free(&L);
  return err;
}
