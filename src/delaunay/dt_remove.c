/* Delaunay layer: vertex removal (REFERENCE §1.6).  The star of v is replaced by the
 * Delaunay tetrahedralization of its hole (the tets of the Delaunay tetrahedralization of
 * the link vertices that lie inside the link), built by gift-wrapping from the link faces:
 * the tet on the inner side of an open face is the one whose apex, among the link vertices
 * on that side, leaves the others out of its ball (the kernel's perturbed insphere test with
 * the vertices' global ids, so the choice is unique and agrees with the main mesh).  The
 * link faces are Delaunay faces of the link vertices, so each tet found is one of the hole's
 * and the result is exactly the Delaunay tetrahedralization without v.  Before, the link
 * vertices were inserted into a scratch triangulation over the whole box: the link vertices
 * surround v, so every insertion rebuilt part of the scratch hull and three of five tets made
 * lay outside the hole.  The new tets are put in a canonical form (vertex order and order by
 * global ids), so they are a function of the star only, whichever tet the search began with
 * (ranks that hold the same star make the same tets). */
#include "dt_impl.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>

/* A face of the hole: a link face (its outside neighbour in the main mesh) or a face of a
 * tet made here (4k+j: local tet k, face j), open until the tet on its other side is made. */
typedef struct {
  uint32_t key[3]; /* sorted main vertex ids */
  uint32_t out;    /* link face: the outside neighbour (4u+j, I2M_DT_NONE or I2M_DT_REMOTE) */
  uint32_t owner;  /* made face: 4k+j; link face: I2M_DT_NONE */
  uint32_t stamp;  /* entry valid when == the removal's stamp */
  uint8_t closed;
} hole_face_t;

/* An open face to wrap: the tet to be is q with q[at] replaced by the apex found. */
typedef struct {
  uint32_t q[4];
  uint32_t face; /* its entry in the face table */
  uint8_t at;
} open_face_t;

struct i2m_dt_removal {
  hole_face_t *faces; /* open addressing, stamped */
  uint32_t fcap, fstamp;
  open_face_t *queue;
  uint32_t nqueue, cap_queue;
  uint32_t *tv;       /* [4k+i] the tets made (main vertex ids) */
  uint32_t *tn;       /* [4k+i] their neighbours: 4k'+j' (a tet made here) or the outside's word */
  uint8_t *made;      /* [4k+i] does tn name a tet made here? */
  uint32_t ntets, cap_tets;
  uint32_t *order, *rank_of; /* canonical order of the tets made, and its inverse */
  uint8_t *perm;      /* [4k+i] the old index of canonical position i */
  uint32_t *link;     /* the link vertices */
  uint32_t nlink, cap_link;
  uint32_t *vseen;    /* small open hash of the link vertices seen */
  uint32_t vcap, vstamp, *vstamp_of;
};

void removal_free(struct i2m_dt_removal **rmp)
{
  if (!rmp || !*rmp) return;
  struct i2m_dt_removal *rm = *rmp;
  i2m_free(&rm->faces);
  i2m_free(&rm->queue);
  i2m_free(&rm->tv);
  i2m_free(&rm->tn);
  i2m_free(&rm->made);
  i2m_free(&rm->order);
  i2m_free(&rm->rank_of);
  i2m_free(&rm->perm);
  i2m_free(&rm->link);
  i2m_free(&rm->vseen);
  i2m_free(&rm->vstamp_of);
  i2m_free(rmp);
}

static i2m_err_t removal_create(struct i2m_dt_removal **out) { return i2m_calloc(1, sizeof **out, out); }

static void sort3(uint32_t k[3])
{
  uint32_t t;
  if (k[0] > k[1]) { t = k[0]; k[0] = k[1]; k[1] = t; }
  if (k[1] > k[2]) { t = k[1]; k[1] = k[2]; k[2] = t; }
  if (k[0] > k[1]) { t = k[0]; k[0] = k[1]; k[1] = t; }
}

/* The sorted key of the face of q opposite index i. */
static void face_key(const uint32_t q[4], int i, uint32_t k[3])
{
  int n = 0;
  for (int j = 0; j < 4; j++)
    if (j != i) k[n++] = q[j];
  sort3(k);
}

/* ---- the face table ---- */
static i2m_err_t faces_prepare(struct i2m_dt_removal *rm, uint32_t n)
{
  if (8 * n > rm->fcap) {
    uint32_t cap = 256;
    while (cap < 8 * n) cap *= 2;
    i2m_free(&rm->faces);
    rm->fcap = cap;
    rm->fstamp = 0;
    I2M_CALL(i2m_calloc(cap, sizeof *rm->faces, &rm->faces));
  }
  if (++rm->fstamp == 0) {
    for (uint32_t s = 0; s < rm->fcap; s++) rm->faces[s].stamp = 0;
    rm->fstamp = 1;
  }
  return I2M_OK;
}

/* The entry of face key k: found, or the empty one where it belongs (stamp not current). */
static uint32_t faces_slot(const struct i2m_dt_removal *rm, const uint32_t k[3])
{
  const uint64_t h = ((uint64_t)k[0] * 0x9E3779B97F4A7C15ull) ^ ((uint64_t)k[1] * 0xC2B2AE3D27D4EB4Full) ^
                     ((uint64_t)k[2] * 0x165667B19E3779F9ull);
  uint32_t s = (uint32_t)(h >> 32) & (rm->fcap - 1);
  while (rm->faces[s].stamp == rm->fstamp &&
         (rm->faces[s].key[0] != k[0] || rm->faces[s].key[1] != k[1] || rm->faces[s].key[2] != k[2]))
    s = (s + 1) & (rm->fcap - 1);
  return s;
}

/* The table twice as large, its entries moved, and the open faces' entries with them. */
static i2m_err_t faces_grow(struct i2m_dt_removal *rm, uint32_t from)
{
  hole_face_t *old = rm->faces;
  const uint32_t oldcap = rm->fcap, stamp = rm->fstamp;
  uint32_t *moved = NULL;
  I2M_CALL(i2m_malloc(oldcap, sizeof *moved, &moved));
  rm->faces = NULL;
  i2m_err_t err = i2m_calloc(2 * (size_t)oldcap, sizeof *rm->faces, &rm->faces);
  if (err != I2M_OK) {
    rm->faces = old;
    i2m_free(&moved);
    return err;
  }
  rm->fcap = 2 * oldcap;
  rm->fstamp = 1;
  for (uint32_t s = 0; s < oldcap; s++) {
    if (old[s].stamp != stamp) continue;
    const uint32_t t = faces_slot(rm, old[s].key);
    rm->faces[t] = old[s];
    rm->faces[t].stamp = 1;
    moved[s] = t;
  }
  for (uint32_t h = from; h < rm->nqueue; h++) rm->queue[h].face = moved[rm->queue[h].face];
  i2m_free(&old);
  i2m_free(&moved);
  return I2M_OK;
}

/* ---- step 2: the link vertices and faces ---- */
static bool link_add(struct i2m_dt_removal *rm, uint32_t w)
{
  uint32_t s = (w * 2654435761u) & (rm->vcap - 1);
  while (rm->vstamp_of[s] == rm->vstamp) {
    if (rm->vseen[s] == w) return false;
    s = (s + 1) & (rm->vcap - 1);
  }
  rm->vstamp_of[s] = rm->vstamp;
  rm->vseen[s] = w;
  rm->link[rm->nlink++] = w;
  return true;
}

static i2m_err_t queue_push(struct i2m_dt_removal *rm, const uint32_t q[4], int at, uint32_t face)
{
  if (rm->nqueue == rm->cap_queue) {
    const uint32_t cap = rm->cap_queue ? 2 * rm->cap_queue : 128;
    I2M_CALL(i2m_realloc(cap, sizeof *rm->queue, &rm->queue));
    rm->cap_queue = cap;
  }
  open_face_t *o = &rm->queue[rm->nqueue++];
  memcpy(o->q, q, sizeof o->q);
  o->at = (uint8_t)at;
  o->face = face;
  return I2M_OK;
}

/* The link vertices, and the link faces as open faces (each with v's tet as the tet to be,
 * v to be replaced): star tets in ctx->cav. */
static i2m_dt_status_t link_collect(i2m_dt_ctx_t *ctx, struct i2m_dt_removal *rm, uint32_t v)
{
  const i2m_dt_t *dt = ctx->dt;
  const uint32_t ns = ctx->ncav;
  if (faces_prepare(rm, ns) != I2M_OK || ctx_grow_u32(&rm->link, &rm->cap_link, 3 * ns) != I2M_OK)
    return I2M_DT_FULL;
  if (4 * 3 * ns > rm->vcap) {
    uint32_t cap = 256;
    while (cap < 4 * 3 * ns) cap *= 2;
    i2m_free(&rm->vseen);
    i2m_free(&rm->vstamp_of);
    rm->vcap = cap;
    rm->vstamp = 0;
    if (i2m_malloc(cap, sizeof *rm->vseen, &rm->vseen) != I2M_OK ||
        i2m_calloc(cap, sizeof *rm->vstamp_of, &rm->vstamp_of) != I2M_OK)
      return I2M_DT_FULL;
  }
  if (++rm->vstamp == 0) {
    memset(rm->vstamp_of, 0, rm->vcap * sizeof *rm->vstamp_of);
    rm->vstamp = 1;
  }
  rm->nlink = 0;
  rm->nqueue = 0;
  rm->ntets = 0;
  for (uint32_t k = 0; k < ns; k++) {
    const uint32_t t = ctx->cav[k], *tv = dt->tv + 4 * (size_t)t;
    int iv = -1;
    for (int i = 0; i < 4; i++) {
      if (tv[i] == v) iv = i;
      else link_add(rm, tv[i]);
    }
    if (iv < 0) return I2M_DT_FAILED;
    uint32_t key[3];
    face_key(tv, iv, key);
    const uint32_t s = faces_slot(rm, key);
    if (rm->faces[s].stamp == rm->fstamp) return I2M_DT_FAILED; /* a link face twice: corrupt star */
    rm->faces[s] = (hole_face_t){{key[0], key[1], key[2]}, dt->tn[4 * (size_t)t + (uint32_t)iv], I2M_DT_NONE, rm->fstamp, 0};
    if (queue_push(rm, tv, iv, s) != I2M_OK) return I2M_DT_FULL;
  }
  return I2M_DT_OK;
}

/* ---- step 1: the star of v, locked and marked.  A tet is marked only by a thread that holds
 * at least one of its faces (the first one: all four vertices), so that two threads can
 * never mark the same tet, and one's rollback never clears the other's mark. ---- */
static i2m_dt_status_t star_collect(i2m_dt_ctx_t *ctx, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt;
  ctx->ncav = 0;
  if (!ctx_claim(ctx, v)) return I2M_DT_ROLLBACK;
  uint32_t t0 = dt->vtet[v]; /* stable: it contains v, which we hold */
  if (!ctx_claim_tet(ctx, dt->tv + 4 * (size_t)t0)) return I2M_DT_ROLLBACK;
  if (ctx_cavity_room(ctx, 1) != I2M_OK) return I2M_DT_FULL;
  ctx->cav[ctx->ncav++] = t0;
  meta_store(dt, t0, i2m_dt_meta(dt, t0) | I2M_TM_MARK);
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    uint32_t t = ctx->cav[k];
    const uint32_t *tv = dt->tv + 4 * (size_t)t;
    if (!ctx_claim_tet(ctx, tv)) return I2M_DT_ROLLBACK;
    if (i2m_dt_meta(dt, t) & I2M_TM_FROZEN) return I2M_DT_FROZEN;
    for (uint32_t i = 0; i < 4; i++) {
      const uint32_t n = dt->tn[4 * t + i];
      if (n == I2M_DT_REMOTE) return I2M_DT_FROZEN; /* (another rank's side cannot be seen) */
      if (tv[i] == v) { /* the face opposite v is a link face: the tet across it is rewritten */
        if (ctx->block && n != I2M_DT_NONE && !i2m_dt_block_holds(dt, ctx->block, n >> 2)) return I2M_DT_FROZEN;
        continue;
      }
      uint32_t u = n >> 2;
      if (i2m_dt_meta(dt, u) & I2M_TM_MARK) continue;
      if (ctx_cavity_room(ctx, ctx->ncav + 1) != I2M_OK) return I2M_DT_FULL;
      ctx->cav[ctx->ncav++] = u;
      meta_store(dt, u, i2m_dt_meta(dt, u) | I2M_TM_MARK);
    }
  }
  return I2M_DT_OK;
}

/* ---- step 3: gift-wrapping ---- */

/* The ball test of one tet against many points: with the tet's first vertex a as the
 * origin, the insphere determinant is linear in the lifted row (x, |x|^2) of the point
 * (x = e - a), so its four cofactors are computed once per tet and each point costs a dot
 * product.  A semi-static bound certifies the sign; else the kernel's exact test decides. */
typedef struct {
  const double *a;
  double c[4]; /* the cofactors of the rows (x, y, z, |x|^2) */
  double p[4]; /* their permanents (the bound) */
} ball_t;

static double minor3(double r[3][4], int i, int j, int k, double *perm)
{
  const double m0 = r[1][j] * r[2][k] - r[1][k] * r[2][j];
  const double m1 = r[1][i] * r[2][k] - r[1][k] * r[2][i];
  const double m2 = r[1][i] * r[2][j] - r[1][j] * r[2][i];
  *perm = fabs(r[0][i]) * (fabs(r[1][j] * r[2][k]) + fabs(r[1][k] * r[2][j])) +
          fabs(r[0][j]) * (fabs(r[1][i] * r[2][k]) + fabs(r[1][k] * r[2][i])) +
          fabs(r[0][k]) * (fabs(r[1][i] * r[2][j]) + fabs(r[1][j] * r[2][i]));
  return r[0][i] * m0 - r[0][j] * m1 + r[0][k] * m2;
}

static void ball_prepare(const i2m_dt_t *dt, const uint32_t q[4], ball_t *B)
{
  double r[3][4];
  B->a = i2m_dt_xyz(dt, q[0]);
  for (int i = 0; i < 3; i++) {
    const double *x = i2m_dt_xyz(dt, q[i + 1]);
    for (int d = 0; d < 3; d++) r[i][d] = x[d] - B->a[d];
    r[i][3] = r[i][0] * r[i][0] + r[i][1] * r[i][1] + r[i][2] * r[i][2];
  }
  B->c[0] = -minor3(r, 1, 2, 3, &B->p[0]);
  B->c[1] = minor3(r, 0, 2, 3, &B->p[1]);
  B->c[2] = -minor3(r, 0, 1, 3, &B->p[2]);
  B->c[3] = minor3(r, 0, 1, 2, &B->p[3]);
}

/* The sign of the tet's insphere test for point e (> 0: in the ball), 0 when the bound does
 * not certify it.  (The determinant of the rows q1-a, q2-a, q3-a, e-a, lifted, has the
 * opposite sign of the kernel's rows translated to e.) */
static int ball_side(const ball_t *B, const double e[3])
{
  const double x = e[0] - B->a[0], y = e[1] - B->a[1], z = e[2] - B->a[2];
  const double l = x * x + y * y + z * z;
  const double det = x * B->c[0] + y * B->c[1] + z * B->c[2] + l * B->c[3];
  const double bound = 64.0 * DBL_EPSILON * (fabs(x) * B->p[0] + fabs(y) * B->p[1] + fabs(z) * B->p[2] + l * B->p[3]);
  return det > bound ? -1 : det < -bound ? 1 : 0;
}

/* The side of the open face's plane, for many points: n.(x - f), with the face's normal n
 * computed once, certified by a semi-static bound; else the exact orientation decides. */
typedef struct {
  const double *f;
  double n[3], p[3]; /* the normal and its components' permanents */
  double sign;       /* +1 or -1: which side makes q with q[at] replaced positive */
} plane_t;

static void plane_prepare(const i2m_dt_t *dt, const uint32_t q[4], int at, plane_t *P)
{
  P->f = i2m_dt_xyz(dt, q[(at + 1) & 3]);
  const double *g = i2m_dt_xyz(dt, q[(at + 2) & 3]), *h = i2m_dt_xyz(dt, q[(at + 3) & 3]);
  const double u[3] = {g[0] - P->f[0], g[1] - P->f[1], g[2] - P->f[2]};
  const double v[3] = {h[0] - P->f[0], h[1] - P->f[1], h[2] - P->f[2]};
  P->n[0] = u[1] * v[2] - u[2] * v[1];
  P->n[1] = u[2] * v[0] - u[0] * v[2];
  P->n[2] = u[0] * v[1] - u[1] * v[0];
  P->p[0] = fabs(u[1] * v[2]) + fabs(u[2] * v[1]);
  P->p[1] = fabs(u[2] * v[0]) + fabs(u[0] * v[2]);
  P->p[2] = fabs(u[0] * v[1]) + fabs(u[1] * v[0]);
  P->sign = (at & 1) ? 1.0 : -1.0; /* (moving row at to the front: a cycle of at places) */
}

static int plane_side(const plane_t *P, const double e[3])
{
  const double x = e[0] - P->f[0], y = e[1] - P->f[1], z = e[2] - P->f[2];
  const double det = P->sign * (x * P->n[0] + y * P->n[1] + z * P->n[2]);
  const double bound = 16.0 * DBL_EPSILON * (fabs(x) * P->p[0] + fabs(y) * P->p[1] + fabs(z) * P->p[2]);
  return det > bound ? 1 : det < -bound ? -1 : 0;
}

/* The apex of the tet on the open side of face o: the link vertex beyond the face (q with
 * q[at] replaced by it positive) whose ball holds no other such vertex.  I2M_DT_NONE if none
 * lies beyond (a corrupt star). */
static uint32_t wrap_apex(const i2m_dt_t *dt, const struct i2m_dt_removal *rm, const open_face_t *o)
{
  uint32_t q[4], best = I2M_DT_NONE;
  memcpy(q, o->q, sizeof q);
  const int at = o->at;
  plane_t P;
  plane_prepare(dt, q, at, &P);
  ball_t B;
  bool ready = false; /* B is best's ball */
  for (uint32_t k = 0; k < rm->nlink; k++) {
    const uint32_t w = rm->link[k];
    if (w == q[(at + 1) & 3] || w == q[(at + 2) & 3] || w == q[(at + 3) & 3]) continue;
    const double *x = i2m_dt_xyz(dt, w);
    int beyond = plane_side(&P, x);
    if (beyond == 0) beyond = tet_orient_replace(dt, q, at, x);
    if (beyond <= 0) continue;
    if (best != I2M_DT_NONE) {
      if (!ready) {
        q[at] = best;
        ball_prepare(dt, q, &B);
        ready = true;
      }
      int side = ball_side(&B, x);
      if (side == 0) side = tet_insphere(dt, q, x, i2m_dt_gid(dt, w));
      if (side <= 0) continue;
    }
    best = w;
    ready = false;
  }
  return best;
}

static i2m_err_t tets_room(struct i2m_dt_removal *rm)
{
  if (rm->ntets < rm->cap_tets) return I2M_OK;
  const uint32_t cap = rm->cap_tets ? 2 * rm->cap_tets : 64;
  I2M_CALL(i2m_realloc(4 * (size_t)cap, sizeof *rm->tv, &rm->tv));
  I2M_CALL(i2m_realloc(4 * (size_t)cap, sizeof *rm->tn, &rm->tn));
  I2M_CALL(i2m_realloc(4 * (size_t)cap, sizeof *rm->made, &rm->made));
  I2M_CALL(i2m_realloc(4 * (size_t)cap, sizeof *rm->perm, &rm->perm));
  I2M_CALL(i2m_realloc(cap, sizeof *rm->order, &rm->order));
  I2M_CALL(i2m_realloc(cap, sizeof *rm->rank_of, &rm->rank_of));
  rm->cap_tets = cap;
  return I2M_OK;
}

/* Face j of tet k made here meets face entry s: its neighbour is the outside (a link face)
 * or the tet made earlier that opened s. */
static void face_join(struct i2m_dt_removal *rm, uint32_t k, int j, hole_face_t *f)
{
  const uint32_t kj = 4 * k + (uint32_t)j;
  f->closed = 1;
  rm->made[kj] = f->owner != I2M_DT_NONE;
  if (f->owner == I2M_DT_NONE) {
    rm->tn[kj] = f->out;
  } else {
    rm->tn[kj] = f->owner;
    rm->tn[f->owner] = kj;
    rm->made[f->owner] = 1;
  }
}

/* Wraps the hole: every open face gets the tet beyond it, whose other faces close open
 * faces or open new ones, until none is open. */
static i2m_dt_status_t wrap_hole(const i2m_dt_t *dt, struct i2m_dt_removal *rm)
{
  uint32_t used = rm->nqueue;
  const uint32_t max_tets = rm->nlink * rm->nlink + 64; /* (a guard: holes here have a few dozen) */
  for (uint32_t h = 0; h < rm->nqueue; h++) {
    const open_face_t o = rm->queue[h]; /* (a copy: the queue grows) */
    if (rm->faces[o.face].closed) continue;
    const uint32_t apex = wrap_apex(dt, rm, &o);
    if (apex == I2M_DT_NONE || rm->ntets >= max_tets) return I2M_DT_FAILED;
    if (tets_room(rm) != I2M_OK) return I2M_DT_FULL;
    const uint32_t k = rm->ntets++;
    uint32_t *t = rm->tv + 4 * k;
    memcpy(t, o.q, 4 * sizeof *t);
    t[o.at] = apex;
    face_join(rm, k, o.at, &rm->faces[o.face]);
    for (int j = 0; j < 4; j++) {
      if (j == o.at) continue;
      uint32_t key[3];
      face_key(t, j, key);
      uint32_t s = faces_slot(rm, key);
      hole_face_t *f = &rm->faces[s];
      if (f->stamp == rm->fstamp) {
        if (f->closed) return I2M_DT_FAILED; /* a face on three tets */
        face_join(rm, k, j, f);
        continue;
      }
      if (2 * ++used > rm->fcap) { /* (a hole far larger than its star's faces foretold) */
        if (faces_grow(rm, h) != I2M_OK) return I2M_DT_FULL;
        s = faces_slot(rm, key);
        f = &rm->faces[s];
      }
      *f = (hole_face_t){{key[0], key[1], key[2]}, I2M_DT_NONE, 4 * k + (uint32_t)j, rm->fstamp, 0};
      /* the tet beyond face j, seen from there: two of the face's vertices swapped, so that
       * an apex beyond the face (opposite t[j]) makes it positive */
      uint32_t q[4];
      memcpy(q, t, sizeof q);
      const int a = (j + 1) & 3, b = (j + 2) & 3;
      q[a] = t[b];
      q[b] = t[a];
      if (queue_push(rm, q, j, s) != I2M_OK) return I2M_DT_FULL;
    }
  }
  return I2M_DT_OK;
}

/* ---- step 4: canonical form, then the splice into the main mesh ---- */

/* The 12 even permutations of four places (they keep a tet's orientation). */
static const uint8_t EVEN_PERMS[12][4] = {{0, 1, 2, 3}, {0, 2, 3, 1}, {0, 3, 1, 2}, {1, 0, 3, 2}, {1, 2, 0, 3}, {1, 3, 2, 0},
                                         {2, 0, 1, 3}, {2, 1, 3, 0}, {2, 3, 0, 1}, {3, 0, 2, 1}, {3, 1, 0, 2}, {3, 2, 1, 0}};

/* Tet k's vertices in canonical order: the even permutation that puts the smallest global id
 * first and the smallest of the other three second (rm->perm[4k+i]: old index of place i). */
static void canonical_perm(const i2m_dt_t *dt, struct i2m_dt_removal *rm, uint32_t k)
{
  const uint32_t *t = rm->tv + 4 * k;
  i2m_gidx_t g[4];
  for (int i = 0; i < 4; i++) g[i] = i2m_dt_gid(dt, t[i]);
  int best = 0;
  for (int p = 1; p < 12; p++) {
    const uint8_t *a = EVEN_PERMS[p], *b = EVEN_PERMS[best];
    if (g[a[0]] < g[b[0]] || (g[a[0]] == g[b[0]] && g[a[1]] < g[b[1]])) best = p;
  }
  memcpy(rm->perm + 4 * k, EVEN_PERMS[best], 4);
}

/* The global id at canonical place i of tet k made here. */
static i2m_gidx_t canonical_gid(const i2m_dt_t *dt, const struct i2m_dt_removal *rm, uint32_t k, int i)
{
  return i2m_dt_gid(dt, rm->tv[4 * k + rm->perm[4 * k + (uint32_t)i]]);
}

/* Does tet a made here come before tet b (their canonical global ids, lexicographically)? */
static bool canonical_before(const i2m_dt_t *dt, const struct i2m_dt_removal *rm, uint32_t a, uint32_t b)
{
  int i = 0;
  while (i < 3 && canonical_gid(dt, rm, a, i) == canonical_gid(dt, rm, b, i)) i++;
  return canonical_gid(dt, rm, a, i) < canonical_gid(dt, rm, b, i);
}

/* The tets made, in the order of their canonical global ids (insertion sort: a few dozen). */
static void canonical_order(const i2m_dt_t *dt, struct i2m_dt_removal *rm)
{
  for (uint32_t k = 0; k < rm->ntets; k++) {
    canonical_perm(dt, rm, k);
    uint32_t r = k;
    for (; r > 0 && canonical_before(dt, rm, k, rm->order[r - 1]); r--) rm->order[r] = rm->order[r - 1];
    rm->order[r] = k;
  }
  for (uint32_t r = 0; r < rm->ntets; r++) rm->rank_of[rm->order[r]] = r;
}

/* The hole's tets into the main mesh: the star's slots first, then new ones; the star's
 * slots left over are killed. */
static i2m_dt_status_t hole_commit(i2m_dt_ctx_t *ctx, struct i2m_dt_removal *rm, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt;
  const uint32_t nf = rm->ntets, ns = ctx->ncav;
  if (!ctx_ensure_slots(ctx, nf > ns ? nf - ns : 0, 0)) return I2M_DT_FULL;
  if (ctx_grow_u32(&ctx->newt, &ctx->cap_new, nf) != I2M_OK) return I2M_DT_FULL;
  if (ctx_grow_u32(&ctx->slots.pool, &ctx->slots.cap_pool, ctx->slots.npool + ns + 1) != I2M_OK) return I2M_DT_FULL;
  if (ctx_vpool_push(ctx, v) != I2M_OK) return I2M_DT_FULL;
  canonical_order(dt, rm);
  ctx->nnew = 0;
  for (uint32_t r = 0; r < nf; r++) {
    const uint32_t t = r < ns ? ctx->cav[r] : ctx_tet_slot(ctx);
    meta_store(dt, t, meta_reborn(i2m_dt_meta(dt, t)));
    ctx->newt[ctx->nnew++] = t;
  }
  for (uint32_t r = nf; r < ns; r++) {
    const uint32_t t = ctx->cav[r];
    meta_store(dt, t, meta_killed(i2m_dt_meta(dt, t)));
    ctx->slots.pool[ctx->slots.npool++] = t;
  }
  for (uint32_t r = 0; r < nf; r++) {
    const uint32_t k = rm->order[r], t = ctx->newt[r];
    const uint8_t *pk = rm->perm + 4 * k;
    for (uint32_t i = 0; i < 4; i++) {
      const uint32_t w = rm->tv[4 * k + pk[i]];
      dt->tv[4 * (size_t)t + i] = w;
      dt->vtet[w] = t;
    }
    for (uint32_t i = 0; i < 4; i++) {
      const uint32_t word = rm->tn[4 * k + pk[i]];
      if (!rm->made[4 * k + pk[i]]) { /* the outside (or the box's hull, or another rank's) */
        dt->tn[4 * (size_t)t + i] = word;
        if (word < I2M_DT_REMOTE) dt->tn[word] = 4 * t + i;
        continue;
      }
      const uint32_t k2 = word >> 2, j2 = word & 3;
      uint32_t i2 = 0;
      while (rm->perm[4 * k2 + i2] != j2) i2++;
      dt->tn[4 * (size_t)t + i] = 4 * ctx->newt[rm->rank_of[k2]] + i2;
    }
  }
  dt->vkind[v] = I2M_VK_DEAD;
  ctx->n_remove++;
  ctx->n_created += nf;
  ctx->n_killed += ns;
  return I2M_DT_OK;
}

i2m_dt_status_t i2m_dt_remove(i2m_dt_ctx_t *ctx, uint32_t v)
{
  i2m_dt_t *dt = ctx->dt;
  ctx->nnew = 0;
  journal_forget(ctx);
  if (v < 8 || v >= i2m_dt_nverts_slots(dt) || dt->vkind[v] == I2M_VK_DEAD || dt->vkind[v] == I2M_VK_BOX)
    return I2M_DT_STALE;
  if (!ctx->rm && removal_create(&ctx->rm) != I2M_OK) return I2M_DT_FULL;
  i2m_dt_status_t st = star_collect(ctx, v);
  if (st == I2M_DT_OK) st = link_collect(ctx, ctx->rm, v);
  if (st == I2M_DT_OK) st = wrap_hole(dt, ctx->rm);
  if (st == I2M_DT_OK) st = hole_commit(ctx, ctx->rm, v);
  if (st != I2M_DT_OK) {
    for (uint32_t k = 0; k < ctx->ncav; k++) {
      uint32_t t = ctx->cav[k];
      meta_store(dt, t, i2m_dt_meta(dt, t) & ~I2M_TM_MARK);
    }
    i2m_dt_unlock_all(ctx);
    if (st == I2M_DT_ROLLBACK) ctx->n_rollback++;
  }
  ctx->ncav = 0;
  return st;
}

/* ---- moving a vertex in place ---- */

/* Does vertex e lie in the ball of tet tv (positively oriented) with its vertex `at` moved to
 * p?  The perturbed test, with the moved vertex's own global id. */
static int moved_insphere(const i2m_dt_t *dt, const uint32_t *tv, int at, const double p[3], uint32_t e)
{
  const double *q[4];
  for (int j = 0; j < 4; j++) q[j] = j == at ? p : i2m_dt_xyz(dt, tv[j]);
  const double *x = i2m_dt_xyz(dt, e);
  const int s = i2m_insphere_filter(q[0], q[1], q[2], q[3], x);
  if (I2M_LIKELY(s != 0)) return s;
  return i2m_insphere_sos_exact(q[0], q[1], q[2], q[3], x, i2m_dt_gid(dt, tv[0]), i2m_dt_gid(dt, tv[1]),
                                i2m_dt_gid(dt, tv[2]), i2m_dt_gid(dt, tv[3]), i2m_dt_gid(dt, e));
}

static int index_of(const uint32_t *tv, uint32_t v)
{
  for (int i = 0; i < 4; i++)
    if (tv[i] == v) return i;
  return -1;
}

/* With v at p, is every tet of its star (ctx->cav) still positive, and every face of the star
 * locally Delaunay (the vertex across it outside the ball of the tet on this side)?  Then the
 * same tets are the Delaunay tetrahedralization of the moved points (the Delaunay lemma). */
static bool star_stays_delaunay(const i2m_dt_ctx_t *ctx, uint32_t v, const double p[3])
{
  const i2m_dt_t *dt = ctx->dt;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t *tv = dt->tv + 4 * (size_t)ctx->cav[k];
    if (tet_orient_replace(dt, tv, index_of(tv, v), p) <= 0) return false;
  }
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t t = ctx->cav[k], *tv = dt->tv + 4 * (size_t)t;
    const int at = index_of(tv, v);
    for (int i = 0; i < 4; i++) {
      const uint32_t n = dt->tn[4 * (size_t)t + i];
      if (n == I2M_DT_NONE) continue; /* (the box's hull) */
      if (i != at && (n >> 2) < t) continue; /* a face between two tets of the star: once */
      if (moved_insphere(dt, tv, at, p, dt->tv[n]) > 0) return false; /* (tv[4u + j] for n = 4u + j) */
    }
  }
  return true;
}

i2m_dt_status_t i2m_dt_move(i2m_dt_ctx_t *ctx, uint32_t v, const double p_in[3])
{
  i2m_dt_t *dt = ctx->dt;
  ctx->nnew = 0;
  journal_forget(ctx);
  if (v < 8 || v >= i2m_dt_nverts_slots(dt) || dt->vkind[v] == I2M_VK_DEAD || dt->vkind[v] == I2M_VK_BOX)
    return I2M_DT_STALE;
  double snapped[3];
  const double *p = i2m_dt_snap(dt, p_in, snapped);
  i2m_dt_status_t st = star_collect(ctx, v);
  if (st == I2M_DT_OK && !star_stays_delaunay(ctx, v, p)) st = I2M_DT_NOT_IN_CONFLICT;
  if (st == I2M_DT_OK && ctx_grow_u32(&ctx->newt, &ctx->cap_new, ctx->ncav) != I2M_OK) st = I2M_DT_FULL;
  for (uint32_t k = 0; k < ctx->ncav; k++) {
    const uint32_t t = ctx->cav[k];
    meta_store(dt, t, i2m_dt_meta(dt, t) & ~I2M_TM_MARK);
    if (st == I2M_DT_OK) ctx->newt[ctx->nnew++] = t;
  }
  ctx->ncav = 0;
  if (st != I2M_DT_OK) {
    i2m_dt_unlock_all(ctx);
    if (st == I2M_DT_ROLLBACK) ctx->n_rollback++;
    return st;
  }
  double *x = dt->xyzw + 4 * (size_t)v; /* (x[3] keeps the global id) */
  x[0] = p[0];
  x[1] = p[1];
  x[2] = p[2];
  return I2M_DT_OK;
}
