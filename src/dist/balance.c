/* Dist layer: the output tets spread over the ranks after the tasks.  The tasks leave each
 * cell on the rank that refined it last, and the shares drift (the data follows the work): at
 * 2 ranks one often ends with 60-67% of the tets, and extraction, the pieces' write and the
 * quality figures, which each rank does for its own tets, wait for it.  Whole cells move from
 * the most loaded rank to a neighbouring one, as the tasks move them (packed with global ids,
 * joined on the other side by matching faces), until no rank holds more than SCHED_BALANCE_SLACK
 * above the mean.  Every rank computes the same plan from the same counts: no coordinator.
 * Called on the thread that initialised MPI, with no task running. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "i2m/dist.h"
#include "sched.h"

#if I2M_HAVE_MPI

#define TAG_BALANCE 7301

/* This rank's side of the moves: its cells packed and sent, the others' received (in the
 * plan's order: messages between two ranks on one tag arrive in order), then its cells
 * dropped and the others' joined. */
static i2m_err_t carry_out(const i2m_par_t *par, i2m_refine_t *r, const sched_move_t *moves, uint32_t nm, int64_t *bytes)
{
  void **out = NULL, **in = NULL;
  int *len_of = NULL; /* [nm] the bytes of each move's buffer, sent or received */
  uint32_t *gone = NULL, ngone = 0;
  MPI_Request *req = NULL;
  i2m_err_t err = I2M_OK;
  *bytes = 0;
  I2M_CALL_GOTO(err, done, i2m_calloc(nm + 1, sizeof *out, &out));
  I2M_CALL_GOTO(err, done, i2m_calloc(nm + 1, sizeof *in, &in));
  I2M_CALL_GOTO(err, done, i2m_calloc(nm + 1, sizeof *len_of, &len_of));
  I2M_CALL_GOTO(err, done, i2m_calloc(nm + 1, sizeof *gone, &gone));
  I2M_CALL_GOTO(err, done, i2m_calloc(nm + 1, sizeof *req, &req));
  size_t len = 0;
  for (uint32_t k = 0; k < nm && err == I2M_OK; k++)
    if (moves[k].from == par->rank) {
      err = i2m_refine_pack(r, moves[k].cell, &out[k], &len);
      if (err == I2M_OK && len > (size_t)INT32_MAX)
        err = I2M_ERROR(I2M_ERR_MEMORY, "a submesh of more than 2 GB: use a larger --depth");
      if (err == I2M_OK) {
        gone[ngone++] = moves[k].cell;
        len_of[k] = (int)len;
        *bytes += (int64_t)len;
      }
    }
done:
  err = i2m_par_agree(par, err); /* (every buffer packed before anything travels) */
  if (err == I2M_OK) {
    int nreq = 0;
    for (uint32_t k = 0; k < nm; k++)
      if (moves[k].from == par->rank)
        MPI_Isend(out[k], len_of[k], MPI_BYTE, moves[k].to, TAG_BALANCE, par->comm, &req[nreq++]);
    for (uint32_t k = 0; k < nm; k++) {
      if (moves[k].to != par->rank) continue;
      MPI_Status st;
      int count = 0;
      MPI_Probe(moves[k].from, TAG_BALANCE, par->comm, &st);
      MPI_Get_count(&st, MPI_BYTE, &count);
      if (i2m_malloc((size_t)count + 1, 1, &in[k]) != I2M_OK) { /* (its sender waits for it: no way to agree) */
        fprintf(stderr, "i2m: %s%s\n", par->prefix, i2m_error_message());
        i2m_par_abort(par, 1);
      }
      MPI_Recv(in[k], count, MPI_BYTE, moves[k].from, TAG_BALANCE, par->comm, MPI_STATUS_IGNORE);
      len_of[k] = count;
    }
    for (int k = 0; k < nreq; k++) MPI_Wait(&req[k], MPI_STATUS_IGNORE); /* (MPICH's MPI_STATUSES_IGNORE
        trips gcc's -Wstringop-overflow in MPI_Waitall) */
    err = i2m_refine_drop(r, gone, ngone);
    for (uint32_t k = 0; k < nm && err == I2M_OK; k++)
      if (moves[k].to == par->rank) err = i2m_refine_unpack(r, in[k], (size_t)len_of[k], NULL);
  }
  for (uint32_t k = 0; out && in && k < nm; k++) {
    free(out[k]);
    free(in[k]);
  }
  i2m_free(&out);
  i2m_free(&in);
  i2m_free(&len_of);
  i2m_free(&gone);
  i2m_free(&req);
  return i2m_par_agree(par, err);
}

i2m_err_t i2m_dist_balance(const i2m_par_t *par, i2m_refine_t *r, i2m_dist_report_t *rep)
{
  const int P = par->size;
  if (P < 2 || !i2m_refine_dist_location(r)) return I2M_OK;
  const double t0 = i2m_wtime();
  int32_t n[3];
  i2m_refine_tiling_cells(r, n);
  const uint32_t nc = (uint32_t)n[0] * (uint32_t)n[1] * (uint32_t)n[2];
  int64_t *kept = NULL, *load = NULL;
  int32_t *holder = NULL;
  sched_move_t *moves = NULL;
  i2m_err_t err = i2m_calloc(nc, sizeof *kept, &kept);
  if (err == I2M_OK) err = i2m_malloc(nc, sizeof *holder, &holder);
  if (err == I2M_OK) err = i2m_malloc(nc, sizeof *moves, &moves);
  if (err == I2M_OK) err = i2m_malloc((size_t)P, sizeof *load, &load);
  for (uint32_t c = 0; c < nc && err == I2M_OK; c++) err = i2m_refine_tile_kept_tets(r, c, &kept[c]);
  err = i2m_par_agree(par, err);
  if (err == I2M_OK) {
    i2m_par_sum_i64(par, kept, (int)nc); /* (each cell counted by its holder only) */
    memcpy(holder, i2m_refine_dist_location(r), nc * sizeof *holder);
    int64_t total = 0;
    for (uint32_t c = 0; c < nc; c++) total += kept[c];
    for (int q = 0; q < P; q++) load[q] = 0;
    for (uint32_t c = 0; c < nc; c++) load[holder[c]] += kept[c];
    const double before = (double)load[sched_most_loaded(load, P)];
    const uint32_t nm = sched_balance(n, P, kept, holder, moves, load); /* (the same on every rank) */
    const double after = (double)load[sched_most_loaded(load, P)];
    int64_t bytes = 0;
    if (nm) err = carry_out(par, r, moves, nm, &bytes);
    if (err == I2M_OK && nm) err = i2m_par_agree(par, i2m_refine_dist_set_location(r, holder));
    if (err == I2M_OK && nm) err = i2m_dist_exchange_ghosts(par, r);
    i2m_par_sum_i64(par, &bytes, 1);
    if (rep) { /* (after the tasks, and again after a sliver pass: the first call's before) */
      if (!rep->balance_calls++) rep->balance_before = total ? before * P / (double)total : 1.0;
      rep->balance_after = total ? after * P / (double)total : 1.0;
      rep->balance_cells += nm;
      rep->balance_bytes += bytes;
      rep->balance_seconds += i2m_wtime() - t0;
    }
  }
  i2m_free(&kept);
  i2m_free(&holder);
  i2m_free(&moves);
  i2m_free(&load);
  return err;
}

#else

i2m_err_t i2m_dist_balance(const i2m_par_t *par, i2m_refine_t *r, i2m_dist_report_t *rep)
{
  (void)par;
  (void)r;
  (void)rep;
  return I2M_OK;
}

#endif
