/* Dist layer: what the ranks hold, put together on rank 0 (a single output file) or
 * exchanged between neighbours (the labels across the faces between ranks).  Called on the
 * thread that initialised MPI, after the distributed phase. */
#include <stdlib.h>
#include <string.h>

#include "i2m/dist.h"

#if I2M_HAVE_MPI

#define CHUNK ((size_t)1 << 28) /* bytes per message: counts stay far below INT_MAX */

static void send_big(const i2m_par_t *par, const void *buf, size_t bytes, int dest)
{
  const unsigned char *p = buf;
  for (size_t s = 0; s < bytes; s += CHUNK) {
    const size_t k = bytes - s < CHUNK ? bytes - s : CHUNK;
    MPI_Send(p + s, (int)k, MPI_BYTE, dest, 7201, par->comm);
  }
}

static void recv_big(const i2m_par_t *par, void *buf, size_t bytes, int src)
{
  unsigned char *p = buf;
  for (size_t s = 0; s < bytes; s += CHUNK) {
    const size_t k = bytes - s < CHUNK ? bytes - s : CHUNK;
    MPI_Recv(p + s, (int)k, MPI_BYTE, src, 7201, par->comm, MPI_STATUS_IGNORE);
  }
}

/* ---- the whole mesh on rank 0, stitched by global id ---- */

typedef struct {
  int64_t *key; /* gid, -1: empty */
  int32_t *val;
  size_t cap, n;
} idmap_t;

static size_t home(const idmap_t *M, int64_t g)
{
  uint64_t z = (uint64_t)g * 0x9E3779B97F4A7C15ull;
  return (size_t)(z ^ (z >> 29)) & (M->cap - 1);
}

static i2m_err_t idmap_init(idmap_t *M, size_t n)
{
  M->cap = 1024;
  while (M->cap < 2 * n) M->cap *= 2;
  M->n = 0;
  I2M_CALL(i2m_malloc(M->cap, sizeof *M->key, &M->key));
  I2M_CALL(i2m_malloc(M->cap, sizeof *M->val, &M->val));
  for (size_t i = 0; i < M->cap; i++) M->key[i] = -1;
  return I2M_OK;
}

/* The index of global id g, a new one (next) when it is new. */
static int32_t idmap_get(idmap_t *M, int64_t g, int32_t next, bool *fresh)
{
  size_t h = home(M, g);
  while (M->key[h] >= 0 && M->key[h] != g) h = (h + 1) & (M->cap - 1);
  *fresh = M->key[h] < 0;
  if (*fresh) {
    M->key[h] = g;
    M->val[h] = next;
    M->n++;
  }
  return M->val[h];
}

typedef struct {
  int64_t nv, nt, ntri;
} counts_t;

/* Appends a piece (its arrays) to the mesh being stitched: vertices by global id (each once,
 * in the order they first appear), tets and triangles renumbered. */
static i2m_err_t append_piece(i2m_tetmesh_t *all, idmap_t *M, const i2m_tetmesh_t *p, int32_t *map)
{
  for (int64_t v = 0; v < p->nv; v++) {
    bool fresh;
    map[v] = idmap_get(M, p->gid[v], (int32_t)all->nv, &fresh);
    if (!fresh) {
      const double *x = all->xyz + 3 * (size_t)map[v], *y = p->xyz + 3 * (size_t)v;
      I2M_CHECK(x[0] == y[0] && x[1] == y[1] && x[2] == y[2], I2M_ERR_INTERNAL,
                "vertex %lld has two places in two pieces", (long long)p->gid[v]);
      continue;
    }
    memcpy(all->xyz + 3 * (size_t)all->nv, p->xyz + 3 * (size_t)v, 3 * sizeof(double));
    all->nv++;
  }
  for (int64_t t = 0; t < p->nt; t++) {
    for (int i = 0; i < 4; i++) all->tet[4 * all->nt + i] = map[p->tet[4 * t + i]];
    all->tet_label[all->nt++] = p->tet_label[t];
  }
  for (int64_t f = 0; f < p->ntri; f++) {
    for (int i = 0; i < 3; i++) all->tri[3 * all->ntri + i] = map[p->tri[3 * f + i]];
    all->tri_label[2 * all->ntri] = p->tri_label[2 * f];
    all->tri_label[2 * all->ntri + 1] = p->tri_label[2 * f + 1];
    all->ntri++;
  }
  return I2M_OK;
}

/* A piece received from rank q (its arrays; gid included). */
static i2m_err_t receive_piece(const i2m_par_t *par, int q, const counts_t *c, i2m_tetmesh_t **out)
{
  i2m_tetmesh_t *p = NULL;
  I2M_CALL(i2m_tetmesh_create(c->nv, c->nt, c->ntri, &p));
  i2m_err_t err = i2m_malloc((size_t)(c->nv ? c->nv : 1), sizeof *p->gid, &p->gid);
  if (err != I2M_OK) {
    i2m_tetmesh_destroy(&p);
    return err;
  }
  recv_big(par, p->xyz, (size_t)c->nv * 3 * sizeof(double), q);
  recv_big(par, p->gid, (size_t)c->nv * sizeof(int64_t), q);
  recv_big(par, p->tet, (size_t)c->nt * 4 * sizeof(int32_t), q);
  recv_big(par, p->tet_label, (size_t)c->nt * sizeof(int64_t), q);
  recv_big(par, p->tri, (size_t)c->ntri * 3 * sizeof(int32_t), q);
  recv_big(par, p->tri_label, (size_t)c->ntri * 2 * sizeof(int64_t), q);
  *out = p;
  return I2M_OK;
}

i2m_err_t i2m_dist_gather_mesh(const i2m_par_t *par, i2m_tetmesh_t **m)
{
  const i2m_tetmesh_t *mine = *m;
  counts_t c = {mine->nv, mine->nt, mine->ntri}, *all_c = NULL;
  I2M_CHECK(mine->gid, I2M_ERR_INTERNAL, "a piece without global ids");
  if (par->rank == 0) I2M_CALL(i2m_malloc((size_t)par->size, sizeof *all_c, &all_c));
  MPI_Gather(&c, (int)sizeof c, MPI_BYTE, all_c, (int)sizeof c, MPI_BYTE, 0, par->comm);
  if (par->rank != 0) { /* (one rank at a time: rank 0 asks for each piece in turn) */
    int go = 0;
    MPI_Recv(&go, 1, MPI_INT, 0, 7200, par->comm, MPI_STATUS_IGNORE);
    send_big(par, mine->xyz, (size_t)c.nv * 3 * sizeof(double), 0);
    send_big(par, mine->gid, (size_t)c.nv * sizeof(int64_t), 0);
    send_big(par, mine->tet, (size_t)c.nt * 4 * sizeof(int32_t), 0);
    send_big(par, mine->tet_label, (size_t)c.nt * sizeof(int64_t), 0);
    send_big(par, mine->tri, (size_t)c.ntri * 3 * sizeof(int32_t), 0);
    send_big(par, mine->tri_label, (size_t)c.ntri * 2 * sizeof(int64_t), 0);
    return I2M_OK;
  }
  counts_t tot = {0, 0, 0};
  int64_t maxnv = 0;
  for (int q = 0; q < par->size; q++) {
    tot.nv += all_c[q].nv;
    tot.nt += all_c[q].nt;
    tot.ntri += all_c[q].ntri;
    maxnv = all_c[q].nv > maxnv ? all_c[q].nv : maxnv;
  }
  I2M_CHECK(tot.nv < INT32_MAX && tot.nt < INT32_MAX / 4, I2M_ERR_UNSUPPORTED,
            "the mesh has %lld tets: too many for one file here; write pieces (-o NAME.pvtu)", (long long)tot.nt);
  i2m_tetmesh_t *all = NULL, *p = NULL;
  idmap_t M = {NULL, NULL, 0, 0};
  int32_t *map = NULL;
  i2m_err_t err = i2m_tetmesh_create(tot.nv, tot.nt, tot.ntri, &all); /* (nv: an upper bound until the end) */
  if (err == I2M_OK) err = idmap_init(&M, (size_t)tot.nv);
  if (err == I2M_OK) err = i2m_malloc((size_t)(maxnv ? maxnv : 1), sizeof *map, &map);
  if (all) all->nv = all->nt = all->ntri = 0;
  for (int q = 0; q < par->size; q++) {
    if (q > 0) {
      int go = 1;
      MPI_Send(&go, 1, MPI_INT, q, 7200, par->comm);
      i2m_err_t e2 = receive_piece(par, q, &all_c[q], &p);
      if (err == I2M_OK) err = e2;
    }
    if (err == I2M_OK) err = append_piece(all, &M, q == 0 ? mine : p, map);
    i2m_tetmesh_destroy(&p);
  }
  i2m_free(&M.key);
  i2m_free(&M.val);
  i2m_free(&map);
  i2m_free(&all_c);
  if (err != I2M_OK) {
    i2m_tetmesh_destroy(&all);
    return err;
  }
  i2m_tetmesh_destroy(m);
  *m = all;
  return I2M_OK;
}

/* ---- the labels across the faces between ranks ---- */

i2m_err_t i2m_dist_exchange_ghosts(const i2m_par_t *par, i2m_refine_t *r)
{
  const int32_t *holder = i2m_refine_dist_location(r);
  const size_t n = i2m_refine_dist_nfaces(r);
  i2m_face_label_t *faces = NULL, *sorted = NULL, *recv = NULL;
  int *scount = NULL, *rcount = NULL, *sdisp = NULL, *rdisp = NULL;
  const int P = par->size;
  i2m_err_t err = I2M_OK;
  const size_t rec = sizeof(i2m_face_label_t);
  I2M_CALL_GOTO(err, done, i2m_malloc(n + 1, rec, &faces));
  I2M_CALL_GOTO(err, done, i2m_malloc(n + 1, rec, &sorted));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)P, sizeof(int), &scount));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)P, sizeof(int), &rcount));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)P, sizeof(int), &sdisp));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)P, sizeof(int), &rdisp));
  i2m_refine_dist_faces(r, faces);
  for (size_t k = 0; k < n; k++) scount[holder[faces[k].cell]]++;
  for (int q = 1; q < P; q++) sdisp[q] = sdisp[q - 1] + scount[q - 1];
  for (size_t k = 0; k < n; k++) sorted[sdisp[holder[faces[k].cell]]++] = faces[k];
  for (int q = 0; q < P; q++) sdisp[q] -= scount[q];
  MPI_Alltoall(scount, 1, MPI_INT, rcount, 1, MPI_INT, par->comm);
  size_t nr = 0;
  for (int q = 0; q < P; q++) {
    rdisp[q] = (int)nr;
    nr += (size_t)rcount[q];
  }
  I2M_CALL_GOTO(err, done, i2m_malloc(nr + 1, rec, &recv));
  for (int q = 0; q < P; q++) { /* (counts in bytes) */
    scount[q] *= (int)rec;
    sdisp[q] *= (int)rec;
    rcount[q] *= (int)rec;
    rdisp[q] *= (int)rec;
  }
  MPI_Alltoallv(sorted, scount, sdisp, MPI_BYTE, recv, rcount, rdisp, MPI_BYTE, par->comm);
  const int64_t unknown = i2m_refine_dist_ghosts(r, recv, nr);
  I2M_CHECK_GOTO(unknown == 0, err, done, I2M_ERR_INTERNAL,
                 "%lld faces between ranks are known on one side only", (long long)unknown);
done:
  i2m_free(&faces);
  i2m_free(&sorted);
  i2m_free(&recv);
  i2m_free(&scount);
  i2m_free(&rcount);
  i2m_free(&sdisp);
  i2m_free(&rdisp);
  return err;
}

#else

i2m_err_t i2m_dist_gather_mesh(const i2m_par_t *par, i2m_tetmesh_t **m)
{
  (void)par;
  (void)m;
  return I2M_OK;
}

i2m_err_t i2m_dist_exchange_ghosts(const i2m_par_t *par, i2m_refine_t *r)
{
  (void)par;
  (void)r;
  return I2M_OK;
}

#endif

/* ---- the quality figures of the pieces, for the whole mesh ---- */

#if I2M_HAVE_MPI
void i2m_dist_reduce_quality(const i2m_par_t *par, i2m_quality_t *q)
{
  if (!par->mpi || par->size == 1) return;
  MPI_Allreduce(MPI_IN_PLACE, &q->min_dihedral, 1, MPI_DOUBLE, MPI_MIN, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, &q->max_dihedral, 1, MPI_DOUBLE, MPI_MAX, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, q->dihedral_hist, 180, MPI_INT64_T, MPI_SUM, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, q->bands.below, I2M_DIHEDRAL_NLOW, MPI_INT64_T, MPI_SUM, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, q->bands.above, I2M_DIHEDRAL_NHIGH, MPI_INT64_T, MPI_SUM, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, &q->max_radius_edge, 1, MPI_DOUBLE, MPI_MAX, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, &q->n_ratio_above, 1, MPI_INT64_T, MPI_SUM, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, &q->min_facet_angle, 1, MPI_DOUBLE, MPI_MIN, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, &q->n_facet_below, 1, MPI_INT64_T, MPI_SUM, par->comm);
  MPI_Allreduce(MPI_IN_PLACE, &q->n_facet_below_junction, 1, MPI_INT64_T, MPI_SUM, par->comm);
  for (int l = 0; l < q->nlabels; l++) {
    MPI_Allreduce(MPI_IN_PLACE, &q->labels[l].ntets, 1, MPI_INT64_T, MPI_SUM, par->comm);
    MPI_Allreduce(MPI_IN_PLACE, &q->labels[l].volume, 1, MPI_DOUBLE, MPI_SUM, par->comm);
  }
}
#else
void i2m_dist_reduce_quality(const i2m_par_t *par, i2m_quality_t *q)
{
  (void)par;
  (void)q;
}
#endif

/* ---- the refinement counters of the whole run ---- */

void i2m_dist_sum_stats(const i2m_par_t *par, i2m_refine_stats_t *s)
{
  int64_t *sum[] = {&s->rule[0], &s->rule[1], &s->rule[2], &s->rule[3], &s->rule[4], &s->rule[5], &s->rule[6],
                    &s->rule[7], &s->insertions, &s->removals, &s->rollbacks, &s->failed, &s->duplicates,
                    &s->junction_skips, &s->tets_created, &s->deferred, &s->bridges};
  enum { N = sizeof sum / sizeof *sum };
  int64_t x[N];
  for (int i = 0; i < N; i++) x[i] = *sum[i];
  i2m_par_sum_i64(par, x, N);
  for (int i = 0; i < N; i++) *sum[i] = x[i];
  s->seconds = i2m_par_max(par, s->seconds);
}
