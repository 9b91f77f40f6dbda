/* Dist layer: the nested master-worker protocol (hybrid paper, Figs. 2 and 3).
 *
 * On every rank the thread that initialised MPI runs engine_master while the pool's worker
 * threads refine.  It never blocks in MPI: it polls (MPI_Iprobe, then a receive of a message
 * that has arrived), sends without blocking (MPI_Isend, tested later) and sleeps a little,
 * longer and longer, when nothing happens.
 *
 * Worker side, on every rank (rank 0 included, through the same messages to itself):
 *   IDLE --request--> ASKED --assign--> GATHER --all submeshes here--> RUNNING --job ended-->
 *   feedback, then IDLE (asynchronous mode) or ASKED (deterministic: rank 0 pushes phases).
 * A batch is a few tasks (cells) whose blocks do not overlap; the submeshes of their blocks
 * that other ranks hold are asked for (one request per holder) and joined when all have
 * arrived, while no job runs.  A request for submeshes that this rank holds is answered at
 * once, also while its workers refine (they never touch a cell outside their blocks); the
 * cells sent leave the local mesh at the next moment no job runs.
 *
 * Scheduler side, rank 0 (sched.c): asynchronous mode, a request gets tasks (those whose
 * blocks the rank holds most of first), or a place on the waiting list, or the end; feedback
 * unlocks blocks and serves the waiting list; the run ends when no cell has work and no task
 * is in flight.  Deterministic mode: the tasks of each colour (then the wide tasks, one at a
 * time) go to the ranks at once, and the next phase waits for every rank's feedback, so the
 * tasks run in the order of one process's deterministic mode, and the mesh is the same. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "i2m/dist.h"
#include "sched.h"

#if I2M_HAVE_MPI

/** One enum for every MPI tag of the protocol. */
enum {
  TAG_REQUEST = 7101, /* worker -> 0: tasks wanted (asynchronous mode) */
  TAG_ASSIGN,         /* 0 -> worker: tasks and the Location of their blocks' cells */
  TAG_WAIT,           /* 0 -> worker: on the waiting list */
  TAG_STOP,           /* 0 -> worker: no work is left anywhere */
  TAG_DATAREQ,        /* worker -> holder: the submeshes of these cells */
  TAG_DATA,           /* holder -> worker: one submesh */
  TAG_FEEDBACK        /* worker -> 0: the tasks done and the figures of their blocks' cells */
};

typedef enum { W_IDLE, W_ASKED, W_GATHER, W_RUNNING, W_STOPPED } wstate_t;

typedef struct {
  MPI_Request req;
  void *buf;
} send_t;

typedef struct {
  void *buf;
  size_t len;
} inbox_t;

/* One line of the trace: a task. */
typedef struct {
  int32_t cell, wide, skip; /* (skip: the sides of its cell the task went without, sched_task_t) */
  double start, end;
  int64_t bytes_in, bytes_out, created;
} trace_t;

typedef struct {
  const i2m_par_t *par;
  i2m_refine_t *r;
  i2m_pool_t *pool;
  const i2m_dist_opts_t *o;
  bool det;
  uint32_t max_batch;
  double t0;                   /* the distributed phase's start */
  /* worker side */
  wstate_t ws;
  double t_state;
  sched_task_t *batch;         /* [125] the batch's tasks */
  uint32_t nbatch;
  uint32_t *tiles;             /* [125] the job's tiles */
  int64_t *created;            /* [125] tets each task made (the trace) */
  uint32_t nneed, narrived;    /* submeshes asked for and arrived */
  inbox_t *inbox;
  uint32_t ninbox, cap_inbox;
  uint32_t *drops;             /* cells sent away, to leave the local mesh when no job runs */
  uint32_t ndrops, cap_drops;
  send_t *sends;
  uint32_t nsends, cap_sends;
  int64_t batch_bytes_in, batch_bytes_out;
  double batch_t0;             /* when the batch's job started */
  trace_t *trace;
  size_t ntrace, cap_trace;
  i2m_rank_figures_t fig;
  int64_t batches;
  /* scheduler side (rank 0) */
  sched_t S;
  int stopped;                 /* ranks told to stop */
  bool slivers;                /* the tasks are the sliver perturbation's (one pass over the cells) */
  bool held_only;              /* asynchronous: only tasks whose whole block the rank holds (a sliver round) */
  bool narrow;                 /* asynchronous: tasks of the cells a rank holds, nothing fetched (a sliver round) */
  uint8_t *done;               /* rank 0, slivers: [ncells] cells whose task ran this pass */
  int det_stage, det_color, det_pending;
  bool det_points;             /* this round's tasks insert bridge points only (as one process inserts them at once) */
  uint32_t *wide_list, nwide, wide_next;
  int64_t rounds;
} engine_t;

/* ---- sending and receiving ---- */

static void fail(engine_t *E, const char *what)
{
  fprintf(stderr, "i2m: %s%s\n", E->par->prefix, what);
  i2m_par_abort(E->par, 1);
}

static void check(engine_t *E, i2m_err_t err)
{
  if (err != I2M_OK) fail(E, i2m_error_message());
}

/* Sends a buffer (owned now by the engine until the send completes). */
static void post(engine_t *E, int dest, int tag, void *buf, size_t len, MPI_Datatype type)
{
  if (E->nsends == E->cap_sends) {
    E->cap_sends = E->cap_sends ? 2 * E->cap_sends : 64;
    check(E, i2m_realloc(E->cap_sends, sizeof *E->sends, &E->sends));
  }
  send_t *s = &E->sends[E->nsends++];
  s->buf = buf;
  const size_t unit = type == MPI_INT64_T ? sizeof(int64_t) : 1;
  if (len / unit > (size_t)INT32_MAX) fail(E, "a submesh of more than 2 GB: use a larger --depth");
  MPI_Isend(buf, (int)(len / unit), type, dest, tag, E->par->comm, &s->req);
}

/* A copy of n int64 values, sent. */
static void post_i64(engine_t *E, int dest, int tag, const int64_t *v, size_t n)
{
  int64_t *b = NULL;
  check(E, i2m_malloc(n ? n : 1, sizeof *b, &b));
  if (n) memcpy(b, v, n * sizeof *b);
  post(E, dest, tag, b, n * sizeof *b, MPI_INT64_T);
}

/* Frees the buffers of the sends that completed. */
static bool test_sends(engine_t *E)
{
  bool progress = false;
  for (uint32_t i = 0; i < E->nsends;) {
    int done = 0;
    MPI_Test(&E->sends[i].req, &done, MPI_STATUS_IGNORE);
    if (!done) {
      i++;
      continue;
    }
    free(E->sends[i].buf);
    E->sends[i] = E->sends[--E->nsends];
    progress = true;
  }
  return progress;
}

/* The message that has arrived (status from MPI_Iprobe), received into a new buffer. */
static void *receive(engine_t *E, const MPI_Status *st, MPI_Datatype type, int *count)
{
  MPI_Get_count(st, type, count);
  const size_t unit = type == MPI_INT64_T ? sizeof(int64_t) : 1;
  void *buf = NULL;
  check(E, i2m_malloc((size_t)*count + 1, unit, &buf));
  MPI_Recv(buf, *count, type, st->MPI_SOURCE, st->MPI_TAG, E->par->comm, MPI_STATUS_IGNORE);
  return buf;
}

/* ---- timing: every moment of the master belongs to one figure ---- */

static void enter(engine_t *E, wstate_t ws)
{
  const double now = i2m_wtime(), dt = now - E->t_state;
  switch (E->ws) {
  case W_IDLE:
  case W_ASKED: E->fig.idle += dt; break;
  case W_GATHER:
    E->fig.comm += dt;
    E->fig.wait_data += dt;
    break;
  case W_RUNNING: E->fig.meshing += dt; break;
  default: break;
  }
  E->ws = ws;
  E->t_state = now;
}

/* Time spent on communication work outside the states (packing, joining, merging). */
static double clock_in(void) { return i2m_wtime(); }
static void clock_out(engine_t *E, double t) { E->fig.comm += i2m_wtime() - t; E->t_state += i2m_wtime() - t; }

/* ---- worker side ---- */

/* The cells of the batch's blocks (each once) that this rank holds (a task that skipped
 * sides left the cells beyond them where they were), into cells[]; returns their number. */
static uint32_t batch_cells(engine_t *E, uint32_t **cells)
{
  static const uint32_t none = UINT32_MAX;
  uint32_t n = 0, b[125];
  *cells = NULL;
  check(E, i2m_malloc(125 * (size_t)(E->nbatch ? E->nbatch : 1), sizeof **cells, cells));
  for (uint32_t k = 0; k < E->nbatch; k++) {
    const uint32_t m = sched_block(&E->S, E->batch[k], b);
    for (uint32_t i = 0; i < m; i++) {
      bool seen = false;
      for (uint32_t j = 0; j < n && !seen; j++) seen = (*cells)[j] == b[i];
      if (!seen && b[i] != none && i2m_refine_holds(E->r, b[i])) (*cells)[n++] = b[i];
    }
  }
  return n;
}

static void request_tasks(engine_t *E)
{
  const int64_t msg[2] = {E->par->rank, E->max_batch};
  post_i64(E, 0, TAG_REQUEST, msg, 2);
  enter(E, W_ASKED);
}

/* The cells sent away leave the local mesh (no job runs). */
static void apply_drops(engine_t *E)
{
  const double t = i2m_wtime();
  check(E, i2m_refine_drop(E->r, E->drops, E->ndrops));
  E->ndrops = 0;
  E->fig.drop += i2m_wtime() - t;
}

/* A cell's figures for the scheduler (work, wide work, tets, bridge points): its bad elements,
 * or in a sliver pass its slivers (counted when the pass begins; after a task rank 0 keeps
 * what it knew of the cells, but for those done: counting them again would cost a pass over
 * their tets for every task). */
static void cell_figures(engine_t *E, uint32_t c, bool count, int64_t fig[I2M_TILE_NFIG])
{
  i2m_refine_tile_figures(E->r, c, fig);
  if (!E->slivers) return;
  fig[0] = count ? i2m_refine_tile_sliver_count(E->r, c) : 0;
  fig[1] = fig[3] = fig[4] = fig[5] = 0;
}

/* A task in a message: its cell, then its wide flag and the sides it skips (wide + 2 skip). */
static void put_task(int64_t *m, sched_task_t t)
{
  m[0] = t.cell;
  m[1] = t.wide + 2 * (int64_t)t.skip;
}

static sched_task_t task_of(const int64_t *m)
{
  return (sched_task_t){(uint32_t)m[0], (m[1] & 1) != 0, (uint8_t)(m[1] >> 1)};
}

/* An assignment: tasks, and the holders of their blocks' cells; the submeshes held
 * elsewhere are asked for (one request per holder). */
static void on_assign(engine_t *E, const int64_t *m, int n)
{
  if (n < 2) fail(E, "bad assignment message");
  E->nbatch = (uint32_t)m[0];
  int at = 1;
  for (uint32_t k = 0; k < E->nbatch; k++, at += 2) E->batch[k] = task_of(m + at);
  const int64_t nloc = m[at++];
  int64_t **per = NULL; /* cells to ask each rank for */
  int64_t *count = NULL;
  check(E, i2m_calloc((size_t)E->par->size, sizeof *per, &per));
  check(E, i2m_calloc((size_t)E->par->size, sizeof *count, &count));
  E->nneed = E->narrived = 0;
  E->batch_bytes_in = E->batch_bytes_out = 0;
  for (int64_t i = 0; i < nloc; i++, at += 2) {
    const uint32_t cell = (uint32_t)m[at];
    const int holder = (int)m[at + 1];
    if (holder == E->par->rank) {
      if (!i2m_refine_holds(E->r, cell)) fail(E, "a cell this rank should hold is not here");
      continue;
    }
    if (!per[holder]) check(E, i2m_malloc(nloc + 1, sizeof **per, &per[holder]));
    per[holder][1 + count[holder]++] = cell;
    E->nneed++;
  }
  for (int q = 0; q < E->par->size; q++) {
    if (!count[q]) continue;
    per[q][0] = count[q];
    post_i64(E, q, TAG_DATAREQ, per[q], (size_t)count[q] + 1);
    i2m_free(&per[q]);
  }
  i2m_free(&per);
  i2m_free(&count);
  enter(E, W_GATHER);
}

/* A request for submeshes: each packed and sent at once (also while the workers refine: they
 * never touch these cells); they leave the local mesh when no job runs. */
static void on_datareq(engine_t *E, const int64_t *m, int n, int source)
{
  const double t = clock_in();
  for (int64_t i = 1; i <= m[0] && i < n; i++) {
    const uint32_t cell = (uint32_t)m[i];
    if (!i2m_refine_holds(E->r, cell)) fail(E, "asked for a cell this rank does not hold");
    void *buf = NULL;
    size_t len = 0;
    const double t_pack = i2m_wtime();
    check(E, i2m_refine_pack(E->r, cell, &buf, &len));
    E->fig.pack += i2m_wtime() - t_pack;
    post(E, source, TAG_DATA, buf, len, MPI_BYTE);
    E->fig.tiles_out++;
    E->fig.bytes_out += (int64_t)len;
    E->batch_bytes_out += (int64_t)len;
    if (E->ws == W_RUNNING) E->fig.answered_while_refining++;
    if (E->ndrops == E->cap_drops) {
      E->cap_drops = E->cap_drops ? 2 * E->cap_drops : 64;
      check(E, i2m_realloc(E->cap_drops, sizeof *E->drops, &E->drops));
    }
    E->drops[E->ndrops++] = cell;
  }
  if (E->ws != W_RUNNING) {
    apply_drops(E);
    clock_out(E, t);
  } /* (while the workers refine, packing overlaps meshing) */
}

static void on_data(engine_t *E, void *buf, int len)
{
  if (E->ninbox == E->cap_inbox) {
    E->cap_inbox = E->cap_inbox ? 2 * E->cap_inbox : 64;
    check(E, i2m_realloc(E->cap_inbox, sizeof *E->inbox, &E->inbox));
  }
  E->inbox[E->ninbox++] = (inbox_t){buf, (size_t)len};
  E->narrived++;
  E->fig.tiles_in++;
  E->fig.bytes_in += len;
  E->batch_bytes_in += len;
}

/* The most tets this rank held at once (at a quiescent moment, after submeshes arrived). */
static void note_peak(engine_t *E)
{
  const int64_t n = i2m_dt_live_tets_quiescent(i2m_refine_dt(E->r));
  if (n > E->fig.peak_tets) E->fig.peak_tets = n;
}

/* Every submesh here and no job running: the cells sent away leave, the ones that came are
 * joined, the batch's tiles get their slots, and the job starts. */
static void start_batch(engine_t *E)
{
  const double t = clock_in();
  apply_drops(E);
  const double t_unpack = i2m_wtime();
  for (uint32_t i = 0; i < E->ninbox; i++) {
    check(E, i2m_refine_unpack(E->r, E->inbox[i].buf, E->inbox[i].len, NULL));
    free(E->inbox[i].buf);
  }
  E->ninbox = 0;
  E->fig.unpack += i2m_wtime() - t_unpack;
  bool wide = false;
  for (uint32_t k = 0; k < E->nbatch; k++) {
    E->tiles[k] = E->batch[k].cell;
    wide |= E->batch[k].wide;
    if (!E->batch[k].wide) i2m_refine_tile_skip(E->r, E->batch[k].cell, E->batch[k].skip);
    E->fig.skipping_tasks += E->batch[k].skip != 0;
    i2m_refine_dist_resolve(E->r, E->batch[k].cell);
  }
  if (E->slivers) check(E, i2m_refine_slivers_dist_prepare(E->r, E->tiles, E->nbatch));
  else if (!wide) check(E, i2m_refine_tiles_prepare(E->r, E->tiles, E->nbatch));
  note_peak(E);
  clock_out(E, t);
  const i2m_pool_job_t job = {E->slivers ? I2M_POOL_SLIVERS : wide ? I2M_POOL_WIDE : I2M_POOL_TILES, E->tiles, E->nbatch,
                              E->created};
  for (uint32_t k = 0; k < E->nbatch; k++) E->created[k] = 0;
  enter(E, W_RUNNING);
  E->batch_t0 = i2m_wtime() - E->t0;
  for (uint32_t k = 0; k < E->nbatch; k++)
    if (E->ntrace + k >= E->cap_trace) {
      E->cap_trace = E->cap_trace ? 2 * E->cap_trace : 256;
      check(E, i2m_realloc(E->cap_trace, sizeof *E->trace, &E->trace));
    }
  i2m_pool_start(E->pool, &job);
}

/* The job ended: hand-overs merged, what the workers made filed, the feedback sent. */
static void finish_batch(engine_t *E)
{
  enter(E, W_IDLE);
  const double t = clock_in();
  check(E, i2m_refine_tiling_merge(E->r));
  check(E, i2m_refine_dist_merge(E->r));
  E->fig.merge += i2m_wtime() - t;
  apply_drops(E);
  note_peak(E);
  uint32_t *cells = NULL;
  const uint32_t nc = batch_cells(E, &cells);
  int64_t *m = NULL;
  check(E, i2m_malloc(2 + 2 * (size_t)E->nbatch + (1 + I2M_TILE_NFIG) * (size_t)nc, sizeof *m, &m));
  size_t at = 0;
  m[at++] = E->nbatch;
  for (uint32_t k = 0; k < E->nbatch; k++, at += 2) put_task(m + at, E->batch[k]);
  m[at++] = nc;
  for (uint32_t i = 0; i < nc; i++) {
    m[at++] = cells[i];
    cell_figures(E, cells[i], false, m + at);
    at += I2M_TILE_NFIG;
  }
  post(E, 0, TAG_FEEDBACK, m, at * sizeof *m, MPI_INT64_T);
  i2m_free(&cells);
  const double now = i2m_wtime() - E->t0;
  for (uint32_t k = 0; k < E->nbatch; k++)
    E->trace[E->ntrace++] = (trace_t){(int32_t)E->batch[k].cell, E->batch[k].wide, E->batch[k].skip, E->batch_t0, now,
                                      k == 0 ? E->batch_bytes_in : 0, k == 0 ? E->batch_bytes_out : 0, E->created[k]};
  E->fig.tasks += E->nbatch;
  for (uint32_t k = 0; k < E->nbatch; k++) E->fig.wide_tasks += E->batch[k].wide;
  E->batches++;
  E->nbatch = 0;
  if (E->o->inject_failure == E->par->rank && E->batches == 3) /* (a deterministic phase may have had no task here) */
    fail(E, "injected failure (I2M_INJECT_FAILURE) in the middle of refinement");
  clock_out(E, t);
  if (E->det) enter(E, W_ASKED);
  else request_tasks(E);
}

/* ---- scheduler side (rank 0) ---- */

/* Sends rank q its tasks and the Location of their blocks' cells (the holders before the
 * tasks take them). */
static void send_assign(engine_t *E, int q, const sched_task_t *tasks, uint32_t n, const int32_t *holder_before,
                        const uint32_t *cells, uint32_t ncells)
{
  int64_t *m = NULL;
  check(E, i2m_malloc(2 + 2 * (size_t)n + 2 * (size_t)ncells, sizeof *m, &m));
  size_t at = 0;
  m[at++] = n;
  for (uint32_t k = 0; k < n; k++, at += 2) put_task(m + at, tasks[k]);
  m[at++] = ncells;
  for (uint32_t i = 0; i < ncells; i++) {
    m[at++] = cells[i];
    m[at++] = holder_before[i];
  }
  post(E, q, TAG_ASSIGN, m, at * sizeof *m, MPI_INT64_T);
}

/* The cells of tasks' fetch blocks (each once) and their holders now (before the tasks take
 * them). */
static uint32_t blocks_of(engine_t *E, const sched_task_t *tasks, uint32_t n, uint32_t *cells, int32_t *holder)
{
  uint32_t nc = 0, b[125];
  for (uint32_t k = 0; k < n; k++) {
    const uint32_t m = sched_fetch_block(&E->S, tasks[k], b);
    for (uint32_t i = 0; i < m; i++) {
      bool seen = false;
      for (uint32_t j = 0; j < nc && !seen; j++) seen = cells[j] == b[i];
      if (!seen) {
        holder[nc] = E->S.holder[b[i]];
        cells[nc++] = b[i];
      }
    }
  }
  return nc;
}

/* The cells[0..n) that rank q holds, in place; returns their number. */
static uint32_t only_held(int q, uint32_t *cells, int32_t *holder, uint32_t n)
{
  uint32_t k = 0;
  for (uint32_t i = 0; i < n; i++)
    if (holder[i] == q) {
      cells[k] = cells[i];
      holder[k++] = q;
    }
  return k;
}

/* Gives rank q what can run now (asynchronous mode); false when nothing can. */
static bool try_give(engine_t *E, int q)
{
  sched_task_t tasks[64];
  uint32_t cells[64 * 27 + 125];
  int32_t holder[64 * 27 + 125];
  uint32_t max = E->max_batch < 64 ? E->max_batch : 64;
  /* (the holders are read before sched_pick hands the blocks to q) */
  sched_t *S = &E->S;
  int32_t *saved = NULL;
  check(E, i2m_malloc(S->ncells, sizeof *saved, &saved));
  memcpy(saved, S->holder, S->ncells * sizeof *saved);
  const uint32_t n = E->narrow      ? sched_pick_narrow(S, q, max, tasks)
                     : E->held_only ? sched_pick_held(S, q, max, tasks)
                                    : sched_pick(S, q, max, tasks);
  if (n) {
    int32_t *now = S->holder;
    S->holder = saved; /* the Location before */
    uint32_t nc = blocks_of(E, tasks, n, cells, holder);
    S->holder = now;
    if (E->narrow) nc = only_held(q, cells, holder, nc); /* (nothing to fetch) */
    send_assign(E, q, tasks, n, holder, cells, nc);
    S->waiting[q] = false;
  }
  i2m_free(&saved);
  return n > 0;
}

static void stop_rank(engine_t *E, int q)
{
  post_i64(E, q, TAG_STOP, NULL, 0);
  E->S.done[q] = true;
  E->S.waiting[q] = false;
  E->stopped++;
}

/* Can a task still come (asynchronous mode)?  While some run (their feedback may bring work),
 * or, when a rank may fetch, while any cell has work. */
static bool more_may_come(const engine_t *E)
{
  return E->held_only || E->narrow ? sched_in_flight(&E->S) : sched_busy(&E->S);
}

/* After feedback (asynchronous mode): the waiting list served, or everybody stopped. */
static void serve_waiting(engine_t *E)
{
  for (int q = 0; q < E->par->size; q++)
    if (E->S.waiting[q]) try_give(E, q);
  if (more_may_come(E)) return;
  for (int q = 0; q < E->par->size; q++)
    if (E->S.waiting[q]) stop_rank(E, q);
}

static void on_request(engine_t *E, int q)
{
  if (try_give(E, q)) return;
  if (more_may_come(E)) {
    E->S.waiting[q] = true;
    post_i64(E, q, TAG_WAIT, NULL, 0);
    serve_waiting(E); /* (a stall whose fetch q may not make: another waiting rank may) */
  } else {
    stop_rank(E, q);
  }
}

/* The next phase of the deterministic mode: the tasks of the next colour that has any, else
 * the next wide task, else a new round or the end; every rank gets its assignment (maybe none). */
static void det_next(engine_t *E)
{
  sched_t *S = &E->S;
  const int P = E->par->size;
  sched_task_t *tasks = NULL;
  int *owner = NULL;
  uint32_t *cells = NULL;
  int32_t *holder = NULL;
  check(E, i2m_malloc(S->ncells + 1, sizeof *tasks, &tasks));
  check(E, i2m_malloc(S->ncells + 1, sizeof *owner, &owner));
  check(E, i2m_malloc(27 * (size_t)S->ncells + 125, sizeof *cells, &cells));
  check(E, i2m_malloc(27 * (size_t)S->ncells + 125, sizeof *holder, &holder));
  uint32_t n = 0;
  for (;;) {
    if (E->det_stage == 0) { /* the colours of a round */
      while (n == 0 && E->det_color < 27) {
        int32_t *saved = NULL;
        check(E, i2m_malloc(S->ncells, sizeof *saved, &saved));
        memcpy(saved, S->holder, S->ncells * sizeof *saved);
        n = sched_phase(S, E->det_color++, E->det_points, tasks, owner);
        if (n == UINT32_MAX) fail(E, "out of memory scheduling a phase");
        for (int q = 0; q < P && n; q++) { /* each rank's tasks, with the Location before */
          sched_task_t mine[4096];
          uint32_t k = 0;
          for (uint32_t i = 0; i < n && k < 4096; i++)
            if (owner[i] == q) mine[k++] = tasks[i];
          int32_t *now = S->holder;
          S->holder = saved;
          const uint32_t nc = blocks_of(E, mine, k, cells, holder);
          S->holder = now;
          send_assign(E, q, mine, k, holder, cells, nc);
        }
        i2m_free(&saved);
      }
      if (n) break;
      const bool points_round = E->det_points;
      if (points_round) { /* a round that inserted bridge points only: then rounds of refinement */
        E->det_color = 0;
        E->det_points = sched_has_points(S); /* (points left where slots ran out) */
        if (E->det_points) continue;
      }
      /* the wide pass: its list, then its tasks one at a time; right after the bridge points,
       * the tasks of the points no zone could hold (one process inserts every point before it
       * refines), which insert those only */
      check(E, i2m_realloc(S->ncells + 1, sizeof *E->wide_list, &E->wide_list));
      E->nwide = sched_wide_list(S, points_round, E->wide_list);
      E->wide_next = 0;
      if (points_round && !E->nwide) continue;
      E->det_stage = 1;
    }
    while (n == 0 && E->wide_next < E->nwide) {
      const uint32_t c = E->wide_list[E->wide_next++];
      if (S->wide[c] <= 0) continue;
      const sched_task_t t = {c, true, 0};
      const int q = sched_best_rank(S, t);
      const uint32_t nc = blocks_of(E, &t, 1, cells, holder);
      sched_give(S, q, t);
      for (int p = 0; p < P; p++) send_assign(E, p, &t, p == q, holder, cells, p == q ? nc : 0);
      n = 1;
    }
    if (n) break;
    E->rounds++; /* the end of a round */
    if (!sched_busy(S)) {
      for (int q = 0; q < P; q++) stop_rank(E, q);
      break;
    }
    E->det_stage = 0;
    E->det_color = 0;
    E->det_points = sched_has_points(S);
  }
  E->det_pending = n ? P : 0;
  i2m_free(&tasks);
  i2m_free(&owner);
  i2m_free(&cells);
  i2m_free(&holder);
}

static void on_feedback(engine_t *E, int q, const int64_t *m, int n)
{
  sched_task_t tasks[4096];
  int at = 0;
  const uint32_t nt = (uint32_t)m[at++];
  if (nt > 4096 || n < 2) fail(E, "bad feedback message");
  for (uint32_t k = 0; k < nt; k++, at += 2) tasks[k] = task_of(m + at);
  const uint32_t nc = (uint32_t)m[at++];
  sched_cell_t *cells = NULL;
  check(E, i2m_malloc(nc + 1, sizeof *cells, &cells));
  for (uint32_t i = 0; i < nc; i++, at += 1 + I2M_TILE_NFIG)
    cells[i] = (sched_cell_t){(uint32_t)m[at], m[at + 1], m[at + 2], m[at + 3], m[at + 4], m[at + 5], m[at + 6]};
  if (E->slivers) /* (the slivers of the cells not done yet: as counted when the pass began) */
    for (uint32_t i = 0; i < nc; i++) cells[i].work = E->S.work[cells[i].cell];
  sched_feedback(&E->S, q, tasks, nt, cells, nc);
  i2m_free(&cells);
  if (E->slivers) /* one task per cell and pass: the cells done have no more work in it */
    for (uint32_t k = 0; k < nt; k++) {
      E->done[tasks[k].cell] = 1;
      E->S.work[tasks[k].cell] = 0;
    }
  if (!E->det) {
    serve_waiting(E);
    return;
  }
  if (--E->det_pending == 0) det_next(E);
}

/* ---- the loop ---- */

static bool poll_messages(engine_t *E)
{
  bool progress = false;
  for (;;) {
    int flag = 0;
    MPI_Status st;
    MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, E->par->comm, &flag, &st);
    if (!flag) return progress;
    progress = true;
    int count = 0;
    if (st.MPI_TAG == TAG_DATA) {
      void *buf = receive(E, &st, MPI_BYTE, &count);
      on_data(E, buf, count);
      continue;
    }
    int64_t *m = receive(E, &st, MPI_INT64_T, &count);
    switch (st.MPI_TAG) {
    case TAG_REQUEST: on_request(E, st.MPI_SOURCE); break;
    case TAG_ASSIGN: on_assign(E, m, count); break;
    case TAG_WAIT: break; /* (already ASKED: it waits) */
    case TAG_STOP: enter(E, W_STOPPED); break;
    case TAG_DATAREQ: on_datareq(E, m, count, st.MPI_SOURCE); break;
    case TAG_FEEDBACK: on_feedback(E, st.MPI_SOURCE, m, count); break;
    default: fail(E, "a message of an unknown kind");
    }
    free(m);
  }
}

/* The worker side's state changes that need no message. */
static bool advance(engine_t *E)
{
  if (E->ws == W_IDLE && !E->det) {
    request_tasks(E);
    return true;
  }
  if (E->ws == W_GATHER && E->narrived == E->nneed) {
    if (E->nbatch == 0) { /* (deterministic mode: no task for this rank in this phase) */
      finish_batch(E);
      return true;
    }
    start_batch(E);
    return true;
  }
  i2m_err_t err;
  if (E->ws == W_RUNNING && i2m_pool_finished(E->pool, &err)) {
    check(E, err);
    finish_batch(E);
    return true;
  }
  return false;
}

/* The longest sleep of a master with nothing to do: another rank's request for submeshes
 * waits at most this long for an answer. */
#define NAP_MAX_US 200

static void nap(int *us)
{
  struct timespec ts = {0, (long)*us * 1000};
  nanosleep(&ts, NULL);
  *us = *us < NAP_MAX_US ? *us * 2 : NAP_MAX_US;
}

static bool everyone_stopped(const engine_t *E) { return E->par->rank != 0 || E->stopped == E->par->size; }

static i2m_err_t engine_master(void *ctx, i2m_pool_t *pool)
{
  engine_t *E = ctx;
  E->pool = pool;
  E->t_state = i2m_wtime();
  if (E->par->rank == 0 && E->det) det_next(E);
  if (E->det) enter(E, W_ASKED);
  int us = 20;
  while (E->ws != W_STOPPED || !everyone_stopped(E) || E->nsends) {
    bool progress = poll_messages(E);
    progress |= advance(E);
    progress |= test_sends(E);
    if (progress) us = 20;
    else nap(&us);
  }
  enter(E, W_STOPPED);
  apply_drops(E);
  return I2M_OK;
}

/* ---- setup and the figures ---- */

static i2m_err_t engine_init(engine_t *E, const i2m_par_t *par, i2m_refine_t *r, const i2m_dist_opts_t *o, int T)
{
  memset(E, 0, sizeof *E);
  E->par = par;
  E->r = r;
  E->o = o;
  E->det = o->threads.deterministic;
  E->max_batch = (uint32_t)(2 * T < 2 ? 2 : 2 * T);
  I2M_CALL(i2m_malloc(4096, sizeof *E->batch, &E->batch));
  I2M_CALL(i2m_malloc(4096, sizeof *E->tiles, &E->tiles));
  I2M_CALL(i2m_malloc(4096, sizeof *E->created, &E->created));
  int32_t n[3];
  i2m_refine_tiling_cells(r, n);
  return sched_init(&E->S, n, par->size); /* (its block geometry serves every rank) */
}

/* Before a run of tasks: the scheduler learns every cell's figures from the rank that holds
 * it, and the Location array (collective). */
static i2m_err_t engine_seed(engine_t *E)
{
  sched_t *S = &E->S;
  const uint32_t nc = S->ncells;
  int64_t *fig = NULL;
  const int F = I2M_TILE_NFIG;
  I2M_CALL(i2m_calloc(F * (size_t)nc, sizeof *fig, &fig));
  for (uint32_t c = 0; c < nc; c++)
    if (i2m_refine_holds(E->r, c)) cell_figures(E, c, true, fig + F * c);
  MPI_Allreduce(MPI_IN_PLACE, fig, F * (int)nc, MPI_INT64_T, MPI_SUM, E->par->comm);
  for (uint32_t c = 0; c < nc; c++) {
    S->work[c] = fig[F * c];
    S->wide[c] = fig[F * c + 1];
    S->tets[c] = fig[F * c + 2];
    S->points[c] = fig[F * c + 3];
    S->wpoints[c] = fig[F * c + 4];
    S->skip[c] = (uint8_t)fig[F * c + 5];
    S->lock[c] = 0;
  }
  i2m_free(&fig);
  const int32_t *loc = i2m_refine_dist_location(E->r);
  if (loc) memcpy(S->holder, loc, nc * sizeof *loc);
  for (int q = 0; q < S->nranks; q++) {
    S->inflight[q] = 0;
    S->waiting[q] = S->done[q] = false;
  }
  E->ws = W_IDLE;
  E->stopped = 0;
  E->det_stage = E->det_color = E->det_pending = 0;
  E->det_points = sched_has_points(S);
  E->nbatch = 0;
  if (E->done) memset(E->done, 0, nc);
  return I2M_OK;
}

/* A run of tasks until no cell has work, on T worker threads beside this (MPI) thread; then
 * the Location array and the labels across the faces between ranks on every rank. */
static i2m_err_t engine_run(engine_t *E, const i2m_threads_opts_t *to, i2m_threads_report_t *team)
{
  const i2m_par_t *par = E->par;
  I2M_CALL(i2m_par_agree(par, engine_seed(E)));
  const int pin_offset = par->local_size > 1 ? par->local_rank * to->threads : 0;
  i2m_err_t err = i2m_threads_serve(E->r, to, pin_offset, engine_master, E, team);
  if (err != I2M_OK) { /* (a failure in the loop aborts the run itself: this is the pool's) */
    fprintf(stderr, "i2m: %s%s\n", par->prefix, i2m_error_message());
    i2m_par_abort(par, 1);
  }
  MPI_Bcast(E->S.holder, (int)E->S.ncells, MPI_INT32_T, 0, par->comm); /* (the Location array, final) */
  I2M_CALL(i2m_par_agree(par, i2m_refine_dist_set_location(E->r, E->S.holder)));
  I2M_CALL(i2m_dist_exchange_ghosts(par, E->r));
  return i2m_par_agree(par, i2m_refine_tiling_check_stuck(E->r)); /* (it reads the labels across) */
}

static void engine_free(engine_t *E)
{
  for (uint32_t i = 0; i < E->ninbox; i++) free(E->inbox[i].buf);
  i2m_free(&E->inbox);
  i2m_free(&E->drops);
  i2m_free(&E->sends);
  i2m_free(&E->batch);
  i2m_free(&E->tiles);
  i2m_free(&E->created);
  i2m_free(&E->trace);
  i2m_free(&E->wide_list);
  i2m_free(&E->done);
  sched_free(&E->S);
}

/* The coarse mesh partitioned: each rank gets the submeshes of its share of the cells (rank 0
 * cuts them along a Morton curve into shares of about as many coarse tets), in one go,
 * before the tasks start (blocking MPI: the workers wait). */
static i2m_err_t scatter_coarse(engine_t *E)
{
  const i2m_par_t *par = E->par;
  sched_t *S = &E->S;
  if (par->rank == 0) {
    for (uint32_t c = 0; c < S->ncells; c++) {
      int64_t fig[I2M_TILE_NFIG];
      i2m_refine_tile_figures(E->r, c, fig);
      S->tets[c] = fig[2];
    }
    sched_partition(S);
  }
  MPI_Bcast(S->home, (int)S->ncells, MPI_INT32_T, 0, par->comm);
  memcpy(S->holder, S->home, S->ncells * sizeof *S->holder); /* (where the cells are once sent) */
  i2m_err_t err = I2M_OK;
  if (par->rank == 0) {
    for (int q = 1; q < par->size; q++) {
      int64_t n = 0;
      for (uint32_t c = 0; c < S->ncells; c++) n += S->home[c] == q;
      MPI_Send(&n, 1, MPI_INT64_T, q, TAG_DATA, par->comm);
      for (uint32_t c = 0; c < S->ncells && err == I2M_OK; c++) {
        if (S->home[c] != q) continue;
        void *buf = NULL;
        size_t len = 0;
        err = i2m_refine_pack(E->r, c, &buf, &len);
        if (err != I2M_OK || len > (size_t)INT32_MAX) fail(E, err != I2M_OK ? i2m_error_message() : "a coarse submesh over 2 GB");
        MPI_Send(buf, (int)len, MPI_BYTE, q, TAG_DATA, par->comm);
        free(buf);
        E->fig.tiles_out++;
        E->fig.bytes_out += (int64_t)len;
      }
    }
    uint32_t *away = NULL, naway = 0; /* (the cells sent leave together) */
    if (err == I2M_OK) err = i2m_malloc(S->ncells, sizeof *away, &away);
    for (uint32_t c = 0; c < S->ncells && err == I2M_OK; c++)
      if (S->home[c] != 0) away[naway++] = c;
    if (err == I2M_OK) err = i2m_refine_drop(E->r, away, naway);
    i2m_free(&away);
  } else {
    int64_t n = 0;
    MPI_Recv(&n, 1, MPI_INT64_T, 0, TAG_DATA, par->comm, MPI_STATUS_IGNORE);
    for (int64_t i = 0; i < n && err == I2M_OK; i++) {
      MPI_Status st;
      int len = 0;
      MPI_Probe(0, TAG_DATA, par->comm, &st);
      void *buf = receive(E, &st, MPI_BYTE, &len);
      err = i2m_refine_unpack(E->r, buf, (size_t)len, NULL);
      free(buf);
      E->fig.tiles_in++;
      E->fig.bytes_in += len;
    }
  }
  return err;
}

/* Every rank's figures on every rank. */
static i2m_err_t gather_figures(const i2m_par_t *par, const i2m_rank_figures_t *mine, i2m_dist_report_t *rep)
{
  I2M_CALL(i2m_calloc((size_t)par->size, sizeof *rep->rank, &rep->rank));
  MPI_Allgather(mine, (int)sizeof *mine, MPI_BYTE, rep->rank, (int)sizeof *mine, MPI_BYTE, par->comm);
  for (int q = 0; q < par->size; q++) {
    rep->tasks += rep->rank[q].tasks;
    rep->wide_tasks += rep->rank[q].wide_tasks;
    rep->bytes += rep->rank[q].bytes_in;
    rep->tiles_moved += rep->rank[q].tiles_in;
  }
  return I2M_OK;
}

/* The trace: every rank's lines, written by rank 0 in rank order. */
static i2m_err_t write_trace(const i2m_par_t *par, const engine_t *E, const char *path)
{
  int n = (int)E->ntrace, *counts = NULL, *displs = NULL;
  trace_t *all = NULL;
  i2m_err_t err = I2M_OK;
  if (par->rank == 0) {
    I2M_CALL(i2m_calloc((size_t)par->size, sizeof *counts, &counts));
    I2M_CALL(i2m_calloc((size_t)par->size, sizeof *displs, &displs));
  }
  MPI_Gather(&n, 1, MPI_INT, counts, 1, MPI_INT, 0, par->comm);
  int total = 0;
  if (par->rank == 0)
    for (int q = 0; q < par->size; q++) {
      displs[q] = total * (int)sizeof(trace_t);
      total += counts[q];
      counts[q] *= (int)sizeof(trace_t);
    }
  if (par->rank == 0) err = i2m_malloc((size_t)total + 1, sizeof *all, &all);
  MPI_Gatherv(E->trace, n * (int)sizeof(trace_t), MPI_BYTE, all, counts, displs, MPI_BYTE, 0, par->comm);
  if (par->rank == 0 && err == I2M_OK) {
    i2m_outfile_t out;
    err = i2m_outfile_open(&out, path, "w");
    if (err == I2M_OK) {
      FILE *f = out.f;
      fprintf(f, "# rank cell wide start_s end_s bytes_in bytes_out tets_created skip\n");
      int q = 0;
      for (int i = 0; i < total; i++) {
        while (q + 1 < par->size && i * (int)sizeof(trace_t) >= displs[q + 1]) q++;
        const trace_t *t = &all[i];
        fprintf(f, "%d %d %d %.6f %.6f %lld %lld %lld %d\n", q, t->cell, t->wide, t->start, t->end, (long long)t->bytes_in,
                (long long)t->bytes_out, (long long)t->created, t->skip);
      }
      err = i2m_outfile_commit(&out);
    }
  }
  i2m_free(&all);
  i2m_free(&counts);
  i2m_free(&displs);
  return err;
}

/* The component rule across the ranks: the pieces, the bridge points filed in the cells that
 * hold them, tasks again, until no large component is split (or a few rounds).  When the
 * output is spread, it is spread again after the tasks (they may have moved cells), before the
 * pieces are looked at again: a cell moved after the last look would make extraction build
 * them once more (0.9 s on the knee at 2 ranks). */
static i2m_err_t component_rule(engine_t *E, const i2m_threads_opts_t *to, i2m_threads_report_t *team,
                                i2m_dist_report_t *rep)
{
  for (int round = 0; round < I2M_BRIDGE_ROUNDS; round++) {
    int64_t filed = 0;
    const double t0 = i2m_wtime();
    I2M_CALL(i2m_dist_pieces(E->par, E->r, I2M_WHOLE_MIN_VOXELS));
    const double t1 = i2m_wtime();
    I2M_CALL(i2m_dist_bridge_points(E->par, E->r, round, &filed));
    const double t2 = i2m_wtime();
    if (filed) I2M_CALL(engine_run(E, to, team));
    const double t3 = i2m_wtime();
    if (filed && E->o->spread_output) I2M_CALL(i2m_dist_balance(E->par, E->r, rep));
    i2m_debug("component rule: %lld bridge points; pieces %.2f s, points %.2f s, tasks %.2f s, balance %.2f s",
              (long long)filed, t1 - t0, t2 - t1, t3 - t2, i2m_wtime() - t3);
    if (!filed) break;
  }
  return I2M_OK;
}

i2m_err_t i2m_dist_refine(const i2m_par_t *par, i2m_refine_t *r, const i2m_dist_opts_t *o, i2m_threads_report_t *team,
                          i2m_dist_report_t *rep)
{
  memset(rep, 0, sizeof *rep);
  const double t0 = i2m_wtime();
  const int T = o->threads.threads > 0 ? o->threads.threads : i2m_threads_default();
  int depth = o->threads.depth > 0 ? o->threads.depth : i2m_refine_default_depth(r, o->threads.deterministic ? 0 : par->size * T);
  depth = i2m_par_bcast_int(par, depth); /* (rank 0's: ranks may have other numbers of threads) */
  i2m_refine_set_depth(r, depth); /* (and the background bound: every rank needs it) */
  rep->ranks = par->size;
  rep->depth = depth;
  rep->deterministic = o->threads.deterministic;
  i2m_threads_opts_t to = o->threads;
  to.threads = T;
  i2m_err_t err = I2M_OK;
  if (par->rank == 0) {
    i2m_threads_opts_t tc = to;
    tc.threads = i2m_par_node_threads(par, T); /* (the other ranks of the node wait asleep) */
    err = i2m_threads_coarse(r, &tc, team);
    i2m_threads_report_free(team);
    if (err == I2M_OK && tc.threads != T) err = i2m_refine_set_workers(r, T);
  } else {
    err = i2m_refine_set_workers(r, T);
    if (err == I2M_OK) err = i2m_refine_octree_begin(r);
  }
  I2M_CALL(i2m_par_agree(par, err));
  const double t1 = i2m_wtime();
  I2M_CALL(i2m_par_agree(par, i2m_refine_dist_begin(r, par->rank == 0)));
  engine_t E;
  I2M_CALL(i2m_par_agree(par, engine_init(&E, par, r, o, T)));
  err = i2m_par_agree(par, scatter_coarse(&E));
  E.t0 = i2m_wtime();
  i2m_debug("dist: coarse mesh %.2f s, its distribution %.2f s", t1 - t0, E.t0 - t1);
  E.fig.preprocess = E.t0 - t0;
  if (err == I2M_OK) err = i2m_par_agree(par, i2m_refine_dist_set_location(r, E.S.holder));
  i2m_refine_dist_asynchronous(r, !o->threads.deterministic);
  if (err == I2M_OK) err = engine_run(&E, &to, team);
  if (err == I2M_OK && o->spread_output) /* (before the pieces are built: they would be again) */
    err = i2m_dist_balance(par, r, rep);
  const double t2 = i2m_wtime();
  if (err == I2M_OK) err = component_rule(&E, &to, team, rep);
  i2m_refine_dist_asynchronous(r, false);
  i2m_debug("dist: tasks %.2f s, component rule %.2f s", t2 - E.t0, i2m_wtime() - t2);
  rep->fine_seconds = i2m_par_max(par, i2m_wtime() - E.t0);
  i2m_refine_stats_t st;
  i2m_refine_get_stats(r, &st);
  i2m_debug("dist: %lld elements handed on were found to have nothing to do", (long long)st.judged);
  E.fig.insertions = st.insertions;
  E.fig.removals = st.removals;
  E.fig.tets = i2m_dt_count_tets(i2m_refine_dt(r));
  E.fig.peak_rss = (double)i2m_peak_rss_bytes();
  if (err == I2M_OK) err = i2m_par_agree(par, gather_figures(par, &E.fig, rep));
  if (err == I2M_OK && o->trace) err = i2m_par_agree(par, write_trace(par, &E, o->trace));
  engine_free(&E);
  return err;
}

/* ---- the sliver perturbation under MPI ---- */

/* Two stages, the slivers below the bound, then the caps (too wide angles) too.  One process
 * lifts the worst first in a stage of its own (below 5 degrees); here a task treats its
 * tile's slivers worst first, in rounds of its own (tile_slivers_dist), and a stage of its
 * own cost every cell's block moves once more: without it, the liver, the knee and the brain
 * at 2 and 3 ranks, 15 degrees, came out with no tet below 15 as with it, the pass 15-30%
 * shorter.  In the asynchronous mode a stage opens with a narrow round: each cell's task runs
 * on the rank that holds the cell, on the tets it holds of the block, and nothing moves; a
 * change that would reach another rank's tets stops at the frozen faces between them and waits
 * for the next round, which fetches blocks as before, for the few cells whose slivers are left
 * near the borders of the ranks' shares.  Liver at 2 x 1, 15 degrees: 32.6 MB moved into rank 0
 * instead of 61.1 MB, the pass 2.82 s against 3.19 s; knee, two interleaved pairs: 6.33 / 6.61 s
 * against 7.03 / 7.22 s; every tet within 15..160 degrees in all of them. */
#define SLIVER_ROUNDS 20 /* per stage, as one process: rounds while moves are kept.  (A stage
                            that ended when a round kept under 1/50 of its first's moves left the
                            liver at delta 1, 3 ranks, 212 tets below 15 degrees, smallest 9.6,
                            against 2 and 14.8 without that end, for 17% more time in the pass.) */

/* This rank's sliver figures summed (counts, moves) or at their extreme (angles) over the ranks. */
static void reduce_sliver_stats(const i2m_par_t *par, i2m_sliver_stats_t *st)
{
  int64_t n[6] = {st->slivers_before, st->slivers_after, st->tried, st->kept, st->inserted, st->removed};
  i2m_par_sum_i64(par, n, 6);
  st->slivers_before = n[0];
  st->slivers_after = n[1];
  st->tried = n[2];
  st->kept = n[3];
  st->inserted = n[4];
  st->removed = n[5];
  st->min_before = -i2m_par_max(par, -st->min_before);
  st->min_after = -i2m_par_max(par, -st->min_after);
  st->seconds = i2m_par_max(par, st->seconds);
}

i2m_err_t i2m_dist_perturb_slivers(const i2m_par_t *par, i2m_refine_t *r, const i2m_dist_opts_t *o, double bound,
                                   i2m_sliver_stats_t *st)
{
  memset(st, 0, sizeof *st);
  const int T = o->threads.threads > 0 ? o->threads.threads : i2m_threads_default();
  i2m_threads_opts_t to = o->threads;
  to.threads = T;
  i2m_threads_report_t team;
  memset(&team, 0, sizeof team);
  engine_t E;
  I2M_CALL(i2m_par_agree(par, i2m_refine_slivers_dist_begin(r, bound)));
  i2m_err_t err = i2m_par_agree(par, engine_init(&E, par, r, o, T));
  E.slivers = true;
  if (err == I2M_OK) err = i2m_par_agree(par, i2m_calloc(E.S.ncells, 1, &E.done));
  E.t0 = i2m_wtime();
  int round = 0;
  for (int k = 0; k < 2 && err == I2M_OK; k++) { /* the stages: the slivers, then the caps too */
    if (k == 1) i2m_refine_slivers_caps(r);
    bool fetch = true;
    const bool narrow_first = !E.det; /* (the deterministic mode's rounds do not depend on where cells are) */
    for (int n = 0; n < SLIVER_ROUNDS && err == I2M_OK; n++, round++) { /* rounds while moves are kept */
      /* After a stage's first round its slivers are few (the tasks' own rounds took most of
       * the rest), and a round moves the blocks of their cells: every later round is wide
       * (more targets, farther), where one process has one only after a round that kept
       * nothing (knee and liver at 2 ranks, 15 degrees: 7-8 rounds instead of 8-10), and
       * (asynchronous mode) runs only the tasks whose whole block a rank holds, until one
       * keeps nothing; then a round may fetch again. */
      const int first = narrow_first ? 1 : 0; /* the stage's first fetching round */
      const bool wide = n > first;
      E.narrow = narrow_first && n == 0;
      E.held_only = !fetch && !E.det;
      int64_t before[2], after[2];
      i2m_refine_slivers_dist_moves(r, &before[0], &before[1]);
      i2m_refine_slivers_dist_round(r, bound, round, wide);
      const double t0 = i2m_wtime();
      err = engine_run(&E, &to, &team);
      i2m_threads_report_free(&team);
      i2m_refine_slivers_dist_moves(r, &after[0], &after[1]);
      int64_t kept = after[1] - before[1];
      i2m_par_sum_i64(par, &kept, 1);
      i2m_debug("slivers: %s stage, round %d: %lld moves kept (%.3f s)", k ? "caps" : "slivers", round, (long long)kept,
                i2m_wtime() - t0);
      if (kept == 0 && wide && fetch) break;
      fetch = kept == 0 || E.det || E.narrow;
    }
    E.held_only = E.narrow = false;
  }
  i2m_debug("slivers: this rank's tasks %lld, meshing %.2f s, communication %.2f s (waiting %.2f, packing %.2f, "
            "joining %.2f, dropping %.2f), idle %.2f s, %lld submeshes in (%.1f MB)",
            (long long)E.fig.tasks, E.fig.meshing, E.fig.comm, E.fig.wait_data, E.fig.pack, E.fig.unpack, E.fig.drop,
            E.fig.idle, (long long)E.fig.tiles_in, (double)E.fig.bytes_in / 1e6);
  const i2m_err_t end = i2m_refine_slivers_dist_end(r, st);
  if (err == I2M_OK) err = i2m_par_agree(par, end);
  reduce_sliver_stats(par, st);
  engine_free(&E);
  return err;
}

void i2m_dist_report_free(i2m_dist_report_t *rep) { i2m_free(&rep->rank); }

#else /* built without MPI: one process, the shared-memory path does everything */

i2m_err_t i2m_dist_refine(const i2m_par_t *par, i2m_refine_t *r, const i2m_dist_opts_t *o, i2m_threads_report_t *team,
                          i2m_dist_report_t *rep)
{
  (void)par;
  (void)r;
  (void)o;
  (void)team;
  memset(rep, 0, sizeof *rep);
  return I2M_ERROR(I2M_ERR_UNSUPPORTED, "this i2m was built without MPI");
}

void i2m_dist_report_free(i2m_dist_report_t *rep) { i2m_free(&rep->rank); }

i2m_err_t i2m_dist_perturb_slivers(const i2m_par_t *par, i2m_refine_t *r, const i2m_dist_opts_t *o, double bound,
                                   i2m_sliver_stats_t *st)
{
  (void)par;
  (void)r;
  (void)o;
  (void)bound;
  memset(st, 0, sizeof *st);
  return I2M_ERROR(I2M_ERR_UNSUPPORTED, "this i2m was built without MPI");
}

#endif
