/* Dist layer: the pieces of the whole mesh across the ranks, and the component rule's points
 * (collective steps between the tasks, on the thread that initialised MPI).
 *
 * Each rank finds the parts of its own tets (src/refine/pieces.c).  Two parts of one label on
 * either side of a face between ranks belong to one piece: each rank sends its faces of
 * another rank's, with the global index of their part, to the holder of the cell across
 * (the Location array), which answers nothing but keeps the pairs it finds.  Rank 0 gathers
 * every part and pair, resolves the pieces (the same arithmetic as one process), and sends
 * each rank the pieces and the piece of each of its parts.  The component rule gathers the
 * claims on the voxels of the split components on rank 0, which finds the bridge points and
 * broadcasts them; each rank files those of the cells it holds as their tasks' work. */
#include <stdlib.h>
#include <string.h>

#include "i2m/dist.h"
#include "i2m/refine.h"

#if I2M_HAVE_MPI

/* ---- byte buffers between ranks ---- */

/* Every rank's bytes on rank 0 (*all owned there, *off[q] where rank q's begin, [size + 1]). */
static i2m_err_t gather_bytes(const i2m_par_t *par, const void *mine, size_t len, void **all, size_t **off)
{
  const int P = par->size;
  int64_t n = (int64_t)len;
  int64_t *lens = NULL;
  int *counts = NULL, *displs = NULL;
  *all = NULL;
  *off = NULL;
  i2m_err_t err = I2M_OK;
  if (par->rank == 0) {
    err = i2m_malloc((size_t)P, sizeof *lens, &lens);
    if (err == I2M_OK) err = i2m_malloc((size_t)P + 1, sizeof **off, off);
    if (err == I2M_OK) err = i2m_malloc((size_t)P, sizeof *counts, &counts);
    if (err == I2M_OK) err = i2m_malloc((size_t)P, sizeof *displs, &displs);
  }
  I2M_CALL(i2m_par_agree(par, err));
  MPI_Gather(&n, 1, MPI_INT64_T, lens, 1, MPI_INT64_T, 0, par->comm);
  if (par->rank == 0) {
    (*off)[0] = 0;
    for (int q = 0; q < P; q++) (*off)[q + 1] = (*off)[q] + (size_t)lens[q];
    err = (*off)[P] > (size_t)INT32_MAX ? I2M_ERROR(I2M_ERR_UNSUPPORTED, "more than 2 GB to gather on rank 0")
                                        : i2m_malloc((*off)[P] + 1, 1, all);
    for (int q = 0; q < P && err == I2M_OK; q++) {
      counts[q] = (int)lens[q];
      displs[q] = (int)(*off)[q];
    }
  }
  err = i2m_par_agree(par, err);
  if (err == I2M_OK) MPI_Gatherv(mine, (int)len, MPI_BYTE, *all, counts, displs, MPI_BYTE, 0, par->comm);
  i2m_free(&lens);
  i2m_free(&counts);
  i2m_free(&displs);
  if (err != I2M_OK) {
    i2m_free(all);
    i2m_free(off);
  }
  return err;
}

/* Rank 0's bytes on every rank (*buf owned; on rank 0 it is `mine` copied). */
static i2m_err_t bcast_bytes(const i2m_par_t *par, const void *mine, size_t len, void **buf, size_t *n)
{
  int64_t m = (int64_t)len;
  MPI_Bcast(&m, 1, MPI_INT64_T, 0, par->comm);
  *n = (size_t)m;
  *buf = NULL;
  I2M_CALL(i2m_par_agree(par, m > INT32_MAX ? I2M_ERROR(I2M_ERR_UNSUPPORTED, "more than 2 GB to broadcast")
                                            : i2m_malloc((size_t)m + 1, 1, buf)));
  if (par->rank == 0 && m) memcpy(*buf, mine, (size_t)m);
  MPI_Bcast(*buf, (int)m, MPI_BYTE, 0, par->comm);
  return I2M_OK;
}

/* ---- pairs of parts across the faces between ranks ---- */

typedef struct {
  i2m_gidx_t key[3];
  int64_t part; /* the sender's part, global index */
  uint16_t label;
  uint16_t pad[3];
} face_rec_t;

/* Each face to the holder of the cell across; the pairs (global part indices) found among
 * the faces received. */
static i2m_err_t part_pairs(const i2m_par_t *par, i2m_refine_t *r, const i2m_parts_t *mine, int64_t first,
                            int64_t **pairs, size_t *npairs)
{
  const int P = par->size;
  const int32_t *holder = i2m_refine_dist_location(r);
  face_rec_t *send = NULL, *recv = NULL;
  int *sc = NULL, *rc = NULL, *sd = NULL, *rd = NULL;
  size_t nr = 0;
  *pairs = NULL;
  *npairs = 0;
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, done, i2m_calloc(mine->nfaces + 1, sizeof *send, &send));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)P, sizeof *sc, &sc));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)P, sizeof *rc, &rc));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)P, sizeof *sd, &sd));
  I2M_CALL_GOTO(err, done, i2m_calloc((size_t)P, sizeof *rd, &rd));
  for (size_t k = 0; k < mine->nfaces; k++) {
    I2M_CHECK_GOTO(mine->face[k].cell >= 0 && holder[mine->face[k].cell] >= 0 && holder[mine->face[k].cell] < P, err, done,
                   I2M_ERR_INTERNAL, "a face between ranks without the cell across (%d)", mine->face[k].cell);
    sc[holder[mine->face[k].cell]]++;
  }
  for (int q = 1; q < P; q++) sd[q] = sd[q - 1] + sc[q - 1];
  for (size_t k = 0; k < mine->nfaces; k++) {
    const i2m_part_face_t *f = &mine->face[k];
    face_rec_t *o = &send[sd[holder[f->cell]]++];
    memcpy(o->key, f->key, sizeof o->key);
    o->part = first + f->part;
    o->label = f->label;
  }
  for (int q = 0; q < P; q++) sd[q] -= sc[q];
  MPI_Alltoall(sc, 1, MPI_INT, rc, 1, MPI_INT, par->comm);
  for (int q = 0; q < P; q++) {
    rd[q] = (int)nr;
    nr += (size_t)rc[q];
  }
  err = i2m_malloc(nr + 1, sizeof *recv, &recv);
  if (err == I2M_OK) err = i2m_malloc(2 * nr + 2, sizeof **pairs, pairs);
done:
  err = i2m_par_agree(par, err);
  if (err == I2M_OK) {
    const int rec = (int)sizeof(face_rec_t);
    for (int q = 0; q < P; q++) {
      sc[q] *= rec;
      sd[q] *= rec;
      rc[q] *= rec;
      rd[q] *= rec;
    }
    MPI_Alltoallv(send, sc, sd, MPI_BYTE, recv, rc, rd, MPI_BYTE, par->comm);
    for (size_t k = 0; k < nr; k++) {
      const int64_t p = i2m_refine_part_at_face(r, recv[k].key, recv[k].label);
      if (p < 0) continue;
      (*pairs)[2 * *npairs] = recv[k].part;
      (*pairs)[2 * *npairs + 1] = first + p;
      (*npairs)++;
    }
  }
  i2m_free(&send);
  i2m_free(&recv);
  i2m_free(&sc);
  i2m_free(&rc);
  i2m_free(&sd);
  i2m_free(&rd);
  if (err != I2M_OK) i2m_free(pairs);
  return err;
}

/* ---- every part on rank 0 ---- */

/* The parts, their component entries and areas of every rank, with global part indices. */
static i2m_err_t gather_parts(const i2m_par_t *par, const i2m_parts_t *mine, int64_t first, i2m_parts_t *all,
                              void *owned[3])
{
  i2m_part_comp_t *comp = NULL;
  i2m_part_area_t *area = NULL;
  size_t *off = NULL;
  i2m_err_t err = i2m_malloc(mine->ncomps + 1, sizeof *comp, &comp);
  if (err == I2M_OK) err = i2m_malloc(mine->nareas + 1, sizeof *area, &area);
  for (size_t i = 0; i < mine->ncomps && err == I2M_OK; i++) {
    comp[i] = mine->comp[i];
    comp[i].part = (uint32_t)(first + comp[i].part);
  }
  for (size_t i = 0; i < mine->nareas && err == I2M_OK; i++) {
    area[i] = mine->area[i];
    area[i].part = (uint32_t)(first + area[i].part);
  }
  err = i2m_par_agree(par, err);
  memset(all, 0, sizeof *all);
  if (err == I2M_OK) err = gather_bytes(par, mine->part, mine->nparts * sizeof *mine->part, &owned[0], &off);
  if (err == I2M_OK && par->rank == 0) all->nparts = off[par->size] / sizeof *all->part;
  i2m_free(&off);
  if (err == I2M_OK) err = gather_bytes(par, comp, mine->ncomps * sizeof *comp, &owned[1], &off);
  if (err == I2M_OK && par->rank == 0) all->ncomps = off[par->size] / sizeof *all->comp;
  i2m_free(&off);
  if (err == I2M_OK) err = gather_bytes(par, area, mine->nareas * sizeof *area, &owned[2], &off);
  if (err == I2M_OK && par->rank == 0) all->nareas = off[par->size] / sizeof *all->area;
  i2m_free(&off);
  all->part = owned[0];
  all->comp = owned[1];
  all->area = owned[2];
  i2m_free(&comp);
  i2m_free(&area);
  return err;
}

/* ---- the pieces from rank 0 to every rank ---- */

/* The splits as int64 words: per split comp, label, ngroups, its groups. */
static i2m_err_t splits_words(const i2m_pieces_global_t *G, int64_t **w, size_t *n)
{
  size_t k = 0;
  for (size_t s = 0; s < G->nsplits; s++) k += 3 + G->split[s].ngroups;
  I2M_CALL(i2m_malloc(k + 1, sizeof **w, w));
  *n = 0;
  for (size_t s = 0; s < G->nsplits; s++) {
    (*w)[(*n)++] = G->split[s].comp;
    (*w)[(*n)++] = G->split[s].label;
    (*w)[(*n)++] = G->split[s].ngroups;
    for (uint32_t g = 0; g < G->split[s].ngroups; g++) (*w)[(*n)++] = G->split[s].groups[g];
  }
  return I2M_OK;
}

static i2m_err_t splits_from_words(const int64_t *w, size_t n, i2m_pieces_global_t *G)
{
  for (size_t at = 0; at < n;) {
    I2M_CALL(i2m_realloc(G->nsplits + 1, sizeof *G->split, &G->split));
    i2m_split_t *s = &G->split[G->nsplits++];
    s->comp = w[at++];
    s->label = (uint16_t)w[at++];
    s->ngroups = (uint32_t)w[at++];
    s->groups = NULL;
    I2M_CALL(i2m_malloc(s->ngroups, sizeof *s->groups, &s->groups));
    for (uint32_t g = 0; g < s->ngroups; g++) s->groups[g] = w[at++];
  }
  return I2M_OK;
}

/* Rank 0's G (whole) to every rank: the groups, the splits, the figures, and each rank's
 * slice of part_group (its nparts from first on) into *out. */
static i2m_err_t scatter_pieces(const i2m_par_t *par, const i2m_pieces_global_t *G, int64_t first, size_t nparts,
                                i2m_pieces_global_t *out)
{
  memset(out, 0, sizeof *out);
  void *buf = NULL;
  size_t n = 0;
  int64_t *w = NULL;
  size_t nw = 0;
  I2M_CALL(bcast_bytes(par, par->rank == 0 ? G->group : NULL, par->rank == 0 ? G->ngroups * sizeof *G->group : 0, &buf, &n));
  out->group = buf;
  out->ngroups = n / sizeof *out->group;
  i2m_err_t err = par->rank == 0 ? splits_words(G, &w, &nw) : I2M_OK;
  err = i2m_par_agree(par, err);
  if (err == I2M_OK) err = bcast_bytes(par, w, nw * sizeof *w, &buf, &n);
  i2m_free(&w);
  if (err == I2M_OK) err = i2m_par_agree(par, splits_from_words(buf, n / sizeof(int64_t), out));
  i2m_free(&buf);
  int64_t fig[2] = {par->rank == 0 ? G->fragments : 0, par->rank == 0 ? G->fragment_tets : 0};
  MPI_Bcast(fig, 2, MPI_INT64_T, 0, par->comm);
  out->fragments = fig[0];
  out->fragment_tets = fig[1];
  /* part_group: each rank's slice (counts as int64 words) */
  const int P = par->size;
  int *counts = NULL, *displs = NULL;
  int64_t range[2] = {first, (int64_t)nparts}, *ranges = NULL;
  if (err == I2M_OK && par->rank == 0) {
    err = i2m_malloc((size_t)P, sizeof *counts, &counts);
    if (err == I2M_OK) err = i2m_malloc((size_t)P, sizeof *displs, &displs);
    if (err == I2M_OK) err = i2m_malloc(2 * (size_t)P, sizeof *ranges, &ranges);
  }
  if (err == I2M_OK) err = i2m_malloc(nparts + 1, sizeof *out->part_group, &out->part_group);
  err = i2m_par_agree(par, err);
  if (err == I2M_OK) {
    MPI_Gather(range, 2, MPI_INT64_T, ranges, 2, MPI_INT64_T, 0, par->comm);
    for (int q = 0; par->rank == 0 && q < P; q++) {
      displs[q] = (int)ranges[2 * q];
      counts[q] = (int)ranges[2 * q + 1];
    }
    MPI_Scatterv(par->rank == 0 ? G->part_group : NULL, counts, displs, MPI_INT64_T, out->part_group, (int)nparts,
                 MPI_INT64_T, 0, par->comm);
    out->nparts = nparts;
  }
  i2m_free(&counts);
  i2m_free(&displs);
  i2m_free(&ranges);
  if (err != I2M_OK) i2m_pieces_global_free(out);
  return err;
}

i2m_err_t i2m_dist_pieces(const i2m_par_t *par, i2m_refine_t *r, int64_t min_voxels)
{
  int valid = i2m_refine_groups_valid(r); /* (nothing changed since the last call, on any rank) */
  MPI_Allreduce(MPI_IN_PLACE, &valid, 1, MPI_INT, MPI_MIN, par->comm);
  if (valid) return I2M_OK;
  i2m_parts_t mine, all;
  I2M_CALL(i2m_par_agree(par, i2m_refine_parts(r, &mine)));
  int64_t n = (int64_t)mine.nparts, first = 0;
  MPI_Exscan(&n, &first, 1, MPI_INT64_T, MPI_SUM, par->comm);
  if (par->rank == 0) first = 0; /* (MPI_Exscan leaves rank 0's undefined) */
  int64_t *pairs = NULL, *every = NULL;
  size_t npairs = 0, *off = NULL;
  void *owned[3] = {NULL, NULL, NULL};
  i2m_pieces_global_t G, mineG;
  memset(&G, 0, sizeof G);
  I2M_CALL(part_pairs(par, r, &mine, first, &pairs, &npairs));
  i2m_err_t e = I2M_OK; /* (and the pairs the fragments' repair made on this rank) */
  if (mine.npairs) e = i2m_realloc(2 * (npairs + mine.npairs) + 1, sizeof *pairs, &pairs);
  for (size_t k = 0; e == I2M_OK && k < 2 * mine.npairs; k++) pairs[2 * npairs + k] = first + mine.pairs[k];
  if (e == I2M_OK) npairs += mine.npairs;
  e = i2m_par_agree(par, e);
  if (e != I2M_OK) {
    i2m_free(&pairs);
    return e;
  }
  i2m_err_t err = gather_parts(par, &mine, first, &all, owned);
  if (err == I2M_OK) err = gather_bytes(par, pairs, 2 * npairs * sizeof *pairs, (void **)&every, &off);
  i2m_free(&pairs);
  if (err == I2M_OK && par->rank == 0) err = i2m_pieces_resolve(r, &all, every, off[par->size] / (2 * sizeof *every), min_voxels, &G);
  err = i2m_par_agree(par, err);
  for (int k = 0; k < 3; k++) i2m_free(&owned[k]);
  i2m_free(&every);
  i2m_free(&off);
  if (err == I2M_OK) err = scatter_pieces(par, &G, first, mine.nparts, &mineG);
  i2m_pieces_global_free(&G);
  if (err == I2M_OK) err = i2m_par_agree(par, i2m_refine_set_groups(r, &mineG));
  return err;
}

/* ---- the component rule's points ---- */

i2m_err_t i2m_dist_bridge_points(const i2m_par_t *par, i2m_refine_t *r, int round, int64_t *filed_total)
{
  const i2m_pieces_global_t *G;
  i2m_voxel_claim_t *claims = NULL, *every = NULL;
  i2m_bridge_point_t *pts = NULL;
  size_t nc = 0, np = 0, *off = NULL;
  void *buf = NULL;
  size_t len = 0;
  *filed_total = 0;
  I2M_CALL(i2m_par_agree(par, i2m_refine_groups(r, I2M_WHOLE_MIN_VOXELS, &G)));
  if (!G->nsplits) return I2M_OK; /* (every rank has the same splits) */
  I2M_CALL(i2m_par_agree(par, i2m_refine_split_claims(r, G, &claims, &nc)));
  i2m_err_t err = gather_bytes(par, claims, nc * sizeof *claims, (void **)&every, &off);
  i2m_free(&claims);
  if (err == I2M_OK && par->rank == 0) err = i2m_bridge_points(r, G, every, off[par->size] / sizeof *every, round, &pts, &np);
  err = i2m_par_agree(par, err);
  i2m_free(&every);
  i2m_free(&off);
  if (err == I2M_OK) err = bcast_bytes(par, pts, np * sizeof *pts, &buf, &len);
  i2m_free(&pts);
  int64_t filed = 0;
  if (err == I2M_OK) err = i2m_par_agree(par, i2m_refine_file_bridges(r, buf, len / sizeof *pts, &filed));
  i2m_free(&buf);
  i2m_par_sum_i64(par, &filed, 1);
  *filed_total = filed;
  if (err == I2M_OK && filed != (int64_t)(len / sizeof *pts))
    err = I2M_ERROR(I2M_ERR_INTERNAL, "%lld of %zu bridge points found a rank that holds their cell", (long long)filed,
                    len / sizeof *pts);
  return err;
}

#else

i2m_err_t i2m_dist_pieces(const i2m_par_t *par, i2m_refine_t *r, int64_t min_voxels)
{
  (void)par;
  (void)r;
  (void)min_voxels;
  return I2M_OK;
}

i2m_err_t i2m_dist_bridge_points(const i2m_par_t *par, i2m_refine_t *r, int round, int64_t *filed_total)
{
  (void)par;
  (void)r;
  (void)round;
  *filed_total = 0;
  return I2M_OK;
}

#endif
