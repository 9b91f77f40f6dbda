/* Threads layer: the worker team (ARCHITECTURE §5, REFERENCE §2).
 *
 * T OpenMP threads each drive one refine worker on the shared triangulation.  A step that
 * meets a vertex locked by another thread has changed nothing and returns ROLLBACK; the
 * contention manager then makes a thread wait for the progress of the holder only when the
 * holder has the higher index, so waits-for edges always point up: no cycle, no deadlock,
 * and the highest-index busy thread never waits (no livelock).  Nobody holds a lock while
 * waiting.  A thread whose lists run dry registers on the begging list and sleeps; a busy
 * thread that sees a beggar hands it the older half of its backlog, counts it busy again
 * and wakes it.  When all T threads are counted idle, every list is empty and refinement is
 * over.  A step that finds the
 * reserved capacity exhausted asks for a pause: the others stop between steps (holding no
 * locks) or sleep, one thread grows the arrays, all resume.
 *
 * Synchronisation is a pthread mutex and condition variable plus C11 atomics, so that
 * ThreadSanitizer sees every happens-before edge (the OpenMP runtime's own is invisible to
 * it); the team's start and end are atomic release/acquire handshakes for the same reason. */
#include <math.h>
#include <omp.h>
#include <pthread.h>
#include <sched.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#include "threads_impl.h"

/* A counter alone on its cache line: each thread bumps its own every step. */
typedef struct {
  _Atomic uint64_t n;
  char pad[64 - sizeof(_Atomic uint64_t)];
} padded_counter_t;

typedef struct {
  i2m_refine_t *r;
  int T;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  /* under mu */
  int idle, arrived, nbeg;
  int *beggar;      /* [T] stack of sleeping threads that want work */
  bool *has_work;   /* [T] set by a giver */
  uint64_t pause_gen;
  int64_t pauses;
  i2m_err_t err;
  char errmsg[512];
  bool reclassify; /* this phase starts by classifying every tet */
  /* lock-free */
  _Atomic int pause_req, done, nbeggars;
  _Atomic int finished;
  padded_counter_t *progress; /* [T] steps done: what a waiting thread watches */
  i2m_thread_figures_t *fig;  /* [T] each thread writes its own */
  i2m_pinning_t *pin;
} team_t;

#define WAIT_SPINS 2000

/* The team of the running phase.  Threads fetch it with acquire: the parallel region
 * captures no variable of the master's stack (OpenMP runtimes hand those over through
 * synchronisation ThreadSanitizer cannot see).  One team per process at a time. */
static _Atomic(team_t *) active_team;
static _Atomic int team_busy;

static void team_fail(team_t *tm, i2m_err_t err)
{
  pthread_mutex_lock(&tm->mu);
  if (tm->err == I2M_OK) {
    tm->err = err;
    snprintf(tm->errmsg, sizeof tm->errmsg, "%s", i2m_error_message());
  }
  atomic_store_explicit(&tm->done, 1, memory_order_release);
  pthread_cond_broadcast(&tm->cv);
  pthread_mutex_unlock(&tm->mu);
}

/* Waits while another thread grows the arrays (called between steps: no lock held). */
static void pause_arrive(team_t *tm)
{
  pthread_mutex_lock(&tm->mu);
  if (atomic_load_explicit(&tm->pause_req, memory_order_relaxed)) {
    uint64_t g = tm->pause_gen;
    tm->arrived++;
    pthread_cond_broadcast(&tm->cv);
    while (tm->pause_gen == g) pthread_cond_wait(&tm->cv, &tm->mu);
  }
  pthread_mutex_unlock(&tm->mu);
}

/* A step found the capacity exhausted: the first such thread grows the arrays once every
 * other thread has stopped or sleeps; later ones just wait for it.  When the phase ends
 * meanwhile (another thread failed: it left its loop and will never stop here), nothing
 * grows: the team is done. */
static void pause_request(team_t *tm)
{
  pthread_mutex_lock(&tm->mu);
  if (atomic_load_explicit(&tm->pause_req, memory_order_relaxed)) {
    pthread_mutex_unlock(&tm->mu);
    pause_arrive(tm);
    return;
  }
  atomic_store_explicit(&tm->pause_req, 1, memory_order_release);
  while (tm->arrived + tm->idle < tm->T - 1 && !atomic_load_explicit(&tm->done, memory_order_relaxed))
    pthread_cond_wait(&tm->cv, &tm->mu);
  const bool ended = tm->arrived + tm->idle < tm->T - 1;
  i2m_err_t err = ended ? I2M_OK : i2m_refine_grow(tm->r); /* every other thread is stopped or asleep */
  tm->pauses++;
  tm->arrived = 0;
  tm->pause_gen++;
  atomic_store_explicit(&tm->pause_req, 0, memory_order_release);
  pthread_cond_broadcast(&tm->cv);
  pthread_mutex_unlock(&tm->mu);
  if (err != I2M_OK) team_fail(tm, err);
}

/* Lists empty: sleep on the begging list until given work, a pause, or the end. */
static void go_idle(team_t *tm, int k)
{
  double t0 = i2m_wtime();
  atomic_fetch_add_explicit(&tm->progress[k].n, 1, memory_order_release); /* waiters: I hold nothing */
  pthread_mutex_lock(&tm->mu);
  if (!atomic_load_explicit(&tm->pause_req, memory_order_relaxed)) {
    tm->idle++;
    if (tm->idle == tm->T) { /* everybody idle and every list empty: finished */
      atomic_store_explicit(&tm->done, 1, memory_order_release);
      pthread_cond_broadcast(&tm->cv);
    } else {
      tm->has_work[k] = false;
      tm->beggar[tm->nbeg++] = k;
      atomic_store_explicit(&tm->nbeggars, tm->nbeg, memory_order_relaxed);
      pthread_cond_broadcast(&tm->cv); /* a pausing thread counts sleepers */
      while (!tm->has_work[k] && !atomic_load_explicit(&tm->done, memory_order_relaxed))
        pthread_cond_wait(&tm->cv, &tm->mu);
      if (tm->has_work[k]) { /* the giver already counted us busy again */
        pthread_mutex_unlock(&tm->mu);
        tm->fig[k].idle_seconds += i2m_wtime() - t0;
        return;
      }
      for (int i = 0; i < tm->nbeg; i++) /* still listed when woken by the end */
        if (tm->beggar[i] == k) tm->beggar[i--] = tm->beggar[--tm->nbeg];
      atomic_store_explicit(&tm->nbeggars, tm->nbeg, memory_order_relaxed);
    }
    tm->idle--;
  }
  pthread_mutex_unlock(&tm->mu);
  tm->fig[k].idle_seconds += i2m_wtime() - t0;
}

/* A busy thread with a backlog gives the older half to the first beggar and wakes it. */
static void maybe_share(team_t *tm, int k)
{
  if (atomic_load_explicit(&tm->nbeggars, memory_order_relaxed) == 0 || i2m_refine_backlog(tm->r, k) < 4) return;
  pthread_mutex_lock(&tm->mu);
  if (tm->nbeg > 0 && !atomic_load_explicit(&tm->pause_req, memory_order_relaxed)) {
    int b = tm->beggar[--tm->nbeg];
    atomic_store_explicit(&tm->nbeggars, tm->nbeg, memory_order_relaxed);
    tm->fig[k].given += (int64_t)i2m_refine_give(tm->r, k, b); /* b sleeps: its lists are free */
    tm->fig[k].handoffs++;
    tm->has_work[b] = true;
    tm->idle--; /* b counts as busy from now on: nobody may conclude that all are idle */
    pthread_cond_broadcast(&tm->cv);
  }
  pthread_mutex_unlock(&tm->mu);
}

/* After a rollback: a thread waits for the holder's progress only if the holder has the
 * higher index; otherwise it goes on with other elements. */
static void contention(team_t *tm, int k)
{
  int o = i2m_refine_conflict_worker(tm->r, k);
  if (o <= k) return;
  double t0 = i2m_wtime();
  uint64_t p0 = atomic_load_explicit(&tm->progress[o].n, memory_order_acquire);
  tm->fig[k].waits++;
  for (int spin = 0; spin < WAIT_SPINS; spin++) {
    if (atomic_load_explicit(&tm->progress[o].n, memory_order_acquire) != p0 ||
        atomic_load_explicit(&tm->pause_req, memory_order_relaxed) || atomic_load_explicit(&tm->done, memory_order_relaxed))
      break;
    sched_yield();
  }
  tm->fig[k].wait_seconds += i2m_wtime() - t0;
}

static void team_loop(team_t *tm, int k)
{
  i2m_refine_t *r = tm->r;
  double t0 = i2m_wtime();
  for (;;) {
    if (atomic_load_explicit(&tm->pause_req, memory_order_acquire)) pause_arrive(tm);
    if (atomic_load_explicit(&tm->done, memory_order_acquire)) break;
    int s = i2m_refine_step(r, k);
    if (s == I2M_STEP_DONE) {
      atomic_fetch_add_explicit(&tm->progress[k].n, 1, memory_order_release);
      maybe_share(tm, k);
    } else if (s == I2M_STEP_ROLLBACK) {
      contention(tm, k);
    } else if (s == I2M_STEP_FULL) {
      pause_request(tm);
    } else if (s == I2M_STEP_IDLE) {
      go_idle(tm, k);
    } else {
      team_fail(tm, i2m_refine_step_error(r, k));
      break;
    }
  }
  tm->fig[k].busy_seconds += i2m_wtime() - t0 - tm->fig[k].idle_seconds;
}

/* The body of every thread of a phase. */
static void phase_thread(void)
{
  team_t *tm = atomic_load_explicit(&active_team, memory_order_acquire); /* sees the master's writes */
  int k = omp_get_thread_num();
  if (tm->pin && tm->fig[k].core == -2) tm->fig[k].core = pinning_bind_thread(tm->pin, k);
  i2m_err_t err = tm->reclassify ? i2m_refine_reclassify(tm->r, k, tm->T) : I2M_OK;
  if (err != I2M_OK) team_fail(tm, err);
  /* everybody classified before anybody changes the mesh */
  atomic_fetch_add_explicit(&tm->finished, 1, memory_order_acq_rel);
  while (atomic_load_explicit(&tm->finished, memory_order_acquire) < tm->T) sched_yield();
  team_loop(tm, k);
  atomic_fetch_add_explicit(&tm->finished, 1, memory_order_release);
}

/* One parallel phase: every thread runs its loop until all are idle. */
static i2m_err_t run_phase(team_t *tm, bool reclassify)
{
  atomic_store_explicit(&tm->done, 0, memory_order_relaxed);
  atomic_store_explicit(&tm->finished, 0, memory_order_relaxed);
  tm->idle = tm->arrived = tm->nbeg = 0;
  tm->reclassify = reclassify;
  atomic_store_explicit(&active_team, tm, memory_order_release);
  I2M_OMP(omp parallel num_threads(tm->T))
  phase_thread();
  while (atomic_load_explicit(&tm->finished, memory_order_acquire) < 2 * tm->T) sched_yield();
  atomic_store_explicit(&active_team, NULL, memory_order_relaxed);
  i2m_refine_sync(tm->r);
  if (tm->err != I2M_OK) return i2m_error_set(tm->err, __FILE__, __LINE__, "%s", tm->errmsg);
  return I2M_OK;
}

/* Before the team: worker 0 alone until there is enough work to share, then the work is
 * spread over the workers by position. */
static i2m_err_t warm_up(i2m_refine_t *r, int T)
{
  size_t want = 64 * (size_t)T;
  int s = I2M_STEP_DONE;
  while (i2m_refine_backlog(r, 0) < want && (s = i2m_refine_step(r, 0)) == I2M_STEP_DONE) {
  }
  if (s == I2M_STEP_FULL) I2M_CALL(i2m_refine_grow(r));
  if (s == I2M_STEP_ERROR) return i2m_refine_step_error(r, 0);
  return i2m_refine_spread(r);
}

static i2m_err_t team_init(team_t *tm, i2m_refine_t *r, int T, bool pin)
{
  memset(tm, 0, sizeof *tm);
  tm->r = r;
  tm->T = T;
  pthread_mutex_init(&tm->mu, NULL);
  pthread_cond_init(&tm->cv, NULL);
  I2M_CALL(i2m_calloc((size_t)T, sizeof *tm->beggar, &tm->beggar));
  I2M_CALL(i2m_calloc((size_t)T, sizeof *tm->has_work, &tm->has_work));
  I2M_CALL(i2m_calloc((size_t)T, sizeof *tm->fig, &tm->fig));
  I2M_CALL(i2m_malloc((size_t)T, sizeof *tm->progress, &tm->progress));
  for (int k = 0; k < T; k++) {
    atomic_init(&tm->progress[k].n, 0);
    tm->fig[k].core = pin ? -2 : -1; /* -2: to bind at the first phase */
  }
  tm->pin = pin ? pinning_open() : NULL;
  return I2M_OK;
}

static void team_free(team_t *tm)
{
  pinning_close(tm->pin);
  pthread_mutex_destroy(&tm->mu);
  pthread_cond_destroy(&tm->cv);
  i2m_free(&tm->beggar);
  i2m_free(&tm->has_work);
  free((void *)tm->progress);
  i2m_free(&tm->fig);
}

static void report_fill(team_t *tm, i2m_threads_report_t *rep)
{
  rep->threads = tm->T;
  rep->pauses = tm->pauses;
  rep->thread = tm->fig;
  tm->fig = NULL;
  int bound = 0;
  for (int k = 0; k < tm->T; k++) {
    i2m_refine_stats_t s;
    i2m_refine_worker_stats(tm->r, k, &s);
    rep->thread[k].insertions = s.insertions;
    rep->thread[k].removals = s.removals;
    rep->thread[k].rollbacks = s.rollbacks;
    bound += rep->thread[k].core >= 0;
  }
  rep->pinned = bound == tm->T;
  if (!tm->pin) snprintf(rep->binding, sizeof rep->binding, "not bound (--no-pin)");
  else if (rep->pinned)
    snprintf(rep->binding, sizeof rep->binding, "each thread bound to one of %d cores (hwloc)", pinning_cores(tm->pin));
  else snprintf(rep->binding, sizeof rep->binding, "binding failed; threads float");
}

/* ---- the deterministic mode: in each round, the tiles of one colour at a time (threads
 * take tiles in turn), a barrier after each colour, then worker 0's sequential pass ---- */

typedef enum { JOB_CLASSIFY, JOB_TILES, JOB_SLIVERS } job_kind_t;

typedef struct {
  team_t *tm;
  job_kind_t kind;
  const uint32_t *tiles; /* JOB_TILES, JOB_SLIVERS: the phase's tiles */
  uint32_t ntiles;
  _Atomic uint32_t next; /* the next tile to take */
} job_t;

static _Atomic(job_t *) active_job; /* (as active_team: handed over with release/acquire) */

static void job_thread(void)
{
  job_t *jb = atomic_load_explicit(&active_job, memory_order_acquire);
  team_t *tm = jb->tm;
  int k = omp_get_thread_num();
  if (tm->pin && tm->fig[k].core == -2) tm->fig[k].core = pinning_bind_thread(tm->pin, k);
  double t0 = i2m_wtime();
  i2m_err_t err = I2M_OK;
  if (jb->kind == JOB_CLASSIFY) {
    err = i2m_refine_tiling_classify(tm->r, k, tm->T);
  } else {
    for (;;) {
      uint32_t i = atomic_fetch_add_explicit(&jb->next, 1, memory_order_relaxed);
      if (i >= jb->ntiles || err != I2M_OK) break;
      err = jb->kind == JOB_TILES ? i2m_refine_tile_run(tm->r, k, jb->tiles[i]) : i2m_refine_tile_slivers(tm->r, k, jb->tiles[i]);
    }
  }
  tm->fig[k].busy_seconds += i2m_wtime() - t0;
  if (err != I2M_OK) team_fail(tm, err);
  atomic_fetch_add_explicit(&tm->finished, 1, memory_order_release);
}

/* Every thread runs the job; returns when all are done. */
static i2m_err_t run_job(team_t *tm, job_t *jb)
{
  atomic_store_explicit(&tm->finished, 0, memory_order_relaxed);
  atomic_store_explicit(&active_job, jb, memory_order_release);
  I2M_OMP(omp parallel num_threads(tm->T))
  job_thread();
  while (atomic_load_explicit(&tm->finished, memory_order_acquire) < tm->T) sched_yield();
  atomic_store_explicit(&active_job, NULL, memory_order_relaxed);
  if (tm->err != I2M_OK) return i2m_error_set(tm->err, __FILE__, __LINE__, "%s", tm->errmsg);
  return I2M_OK;
}

/* Work done on tiles in rounds (refinement, or the sliver perturbation): per round, the
 * tiles of each colour on the team with a barrier after each colour, then worker 0's
 * sequential pass. */
typedef struct {
  job_kind_t kind;
  bool (*has_work)(const i2m_refine_t *r);
  i2m_err_t (*phase)(i2m_refine_t *r, int color, const uint32_t **tiles, uint32_t *ntiles);
  i2m_err_t (*merge)(i2m_refine_t *r);
  i2m_err_t (*sequential)(i2m_refine_t *r);
} tiled_work_t;

static const tiled_work_t REFINE_TILES = {JOB_TILES, i2m_refine_tiling_has_work, i2m_refine_tiling_phase,
                                          i2m_refine_tiling_merge, i2m_refine_tiling_sequential};
static const tiled_work_t SLIVER_TILES = {JOB_SLIVERS, i2m_refine_slivers_has_work, i2m_refine_slivers_phase,
                                          i2m_refine_slivers_merge, i2m_refine_slivers_sequential};

/* Rounds until nothing is left; *phases counts the colours that had tiles. */
static i2m_err_t tiled_rounds(team_t *tm, const tiled_work_t *wk, int64_t *phases)
{
  i2m_refine_t *r = tm->r;
  i2m_err_t err = I2M_OK;
  while (err == I2M_OK && wk->has_work(r)) {
    for (int color = 0; color < i2m_refine_tiling_colors(r) && err == I2M_OK; color++) {
      job_t jb = {tm, wk->kind, NULL, 0, 0};
      err = wk->phase(r, color, &jb.tiles, &jb.ntiles);
      if (err != I2M_OK || jb.ntiles == 0) continue;
      err = run_job(tm, &jb);
      if (err == I2M_OK) err = wk->merge(r);
      (*phases)++;
    }
    if (err == I2M_OK) err = wk->sequential(r);
  }
  return err;
}

/* Refinement's rounds on the tiles, then the tiling's figures; the tiling ends unless keep. */
static i2m_err_t run_tiled(team_t *tm, i2m_threads_report_t *rep, bool keep)
{
  i2m_refine_t *r = tm->r;
  i2m_err_t err = tiled_rounds(tm, &REFINE_TILES, &rep->phases);
  if (err == I2M_OK) err = i2m_refine_tiling_check_stuck(r);
  double side;
  int64_t rounds, seq;
  i2m_refine_tiling_figures(r, &side, &rounds, &seq);
  rep->tile_side = side; /* (the fine phase's, the last one set) */
  rep->rounds += rounds;
  rep->sequential_ops += seq;
  {
    i2m_refine_stats_t st;
    i2m_refine_get_stats(r, &st);
    i2m_debug("tiled phase: side %.3g mm, %lld rounds, %lld sequential ops; so far %lld deferred, %lld insertions", side,
              (long long)rounds, (long long)seq, (long long)st.deferred, (long long)st.insertions);
  }
  if (!keep) i2m_refine_tiling_end(r);
  return err;
}

/* One round of the component rule (between phases): *more when it inserted bridges, whose
 * tets now wait on worker 0 for refinement. */
static i2m_err_t bridge_round(i2m_refine_t *r, bool *more)
{
  int64_t splits, inserted;
  const double t0 = i2m_wtime();
  I2M_CALL(i2m_refine_bridge_splits(r, I2M_WHOLE_MIN_VOXELS, &splits, &inserted));
  i2m_debug("component rule: %lld split components, %lld bridge vertices, %.2f s", (long long)splits, (long long)inserted,
            i2m_wtime() - t0);
  if (splits && !inserted) /* (the split stays: say why, for the warning that follows) */
    i2m_warn("i2m: the component rule found %lld split components but could place no bridge vertex", (long long)splits);
  *more = inserted > 0;
  return I2M_OK;
}

/* The deterministic mode's phases: the coarse one, then every tet classified again and the
 * fine one, then the component rule and refinement in turn. */
static i2m_err_t refine_deterministic(team_t *tm, const i2m_threads_opts_t *o, i2m_threads_report_t *rep)
{
  i2m_refine_t *r = tm->r;
  bool coarse = o->coarse_factor > 1;
  double t0 = i2m_wtime();
  i2m_err_t err = I2M_OK;
  if (coarse) i2m_refine_set_depth(r, o->depth > 0 ? o->depth : i2m_refine_default_depth(r, 0)); /* (and the bound) */
  else i2m_refine_tiling_bound(r);
  rep->depth = coarse ? i2m_refine_depth(r) : 0;
  if (coarse) {
    i2m_refine_set_scale(r, o->coarse_factor);
    err = i2m_refine_tiling_begin(r);
    if (err == I2M_OK) err = run_tiled(tm, rep, false);
    i2m_refine_set_scale(r, 1.0);
  }
  double t1 = i2m_wtime();
  /* the fine phase on the dist layer's subregions, whose zones need the coarse phase's small
   * tets (without one, the coarse tiles and their sequential pass do it all) */
  const bool octree = coarse;
  if (err == I2M_OK) err = octree ? i2m_refine_octree_begin(r) : i2m_refine_tiling_begin(r);
  if (err == I2M_OK && coarse) {
    job_t jb = {tm, JOB_CLASSIFY, NULL, 0, 0};
    err = i2m_refine_tiling_prepare_classify(r);
    if (err == I2M_OK) err = run_job(tm, &jb);
    if (err == I2M_OK) err = i2m_refine_tiling_collect(r);
  }
  /* the component rule; the octree stays (its tiles' global ids go on), its bridge points
   * enter its tiles as the dist layer's tasks insert them (i2m_refine_insert_bridges) */
  if (err == I2M_OK) err = run_tiled(tm, rep, octree);
  for (int round = 0; err == I2M_OK && round < I2M_BRIDGE_ROUNDS; round++) {
    bool more = false;
    err = bridge_round(r, &more);
    if (err == I2M_OK && more && !octree) err = i2m_refine_tiling_begin(r);
    if (err == I2M_OK && more) err = run_tiled(tm, rep, octree);
    if (!more) break;
  }
  i2m_refine_tiling_end(r); /* (after a failure too) */
  rep->coarse_seconds = coarse ? t1 - t0 : 0;
  rep->fine_seconds = i2m_wtime() - t1;
  return err;
}

/* The number of threads a parallel region will really have when T are asked for: every
 * phase waits for all of them at its barriers, so the runtime may not hand out fewer
 * (OMP_DYNAMIC is turned off; OMP_THREAD_LIMIT and a caller's own parallel region without
 * nesting lower the count, with a warning). */
static int team_size(int T)
{
  omp_set_dynamic(0);
  int got = T;
  if (got > omp_get_thread_limit()) got = omp_get_thread_limit();
  if (omp_in_parallel() && omp_get_active_level() >= omp_get_max_active_levels()) got = 1;
  if (got < T) i2m_warn("i2m: %d threads asked for, the OpenMP runtime allows %d (OMP_THREAD_LIMIT or nesting): using %d", T, got, got);
  return got;
}

int i2m_threads_set(int n)
{
  const int was = omp_get_max_threads();
  omp_set_num_threads(n < 1 ? 1 : n);
  return was;
}

void i2m_threads_limit(int n)
{
  const int now = omp_get_max_threads();
  i2m_threads_set(n < now ? n : now);
}

i2m_err_t i2m_threads_refine(i2m_refine_t *r, const i2m_threads_opts_t *o, i2m_threads_report_t *rep)
{
  int T = team_size(o->threads > 0 ? o->threads : i2m_threads_default());
  team_t tm;
  memset(rep, 0, sizeof *rep);
  I2M_CHECK(atomic_exchange(&team_busy, 1) == 0, I2M_ERR_UNSUPPORTED,
            "one parallel refinement at a time per process");
  i2m_err_t err = i2m_refine_set_workers(r, T);
  if (err != I2M_OK) {
    atomic_store(&team_busy, 0);
    return err;
  }
  err = team_init(&tm, r, T, o->pin);
  if (o->deterministic) {
    rep->deterministic = 1;
    if (err == I2M_OK) err = refine_deterministic(&tm, o, rep);
    report_fill(&tm, rep);
    team_free(&tm);
    atomic_store(&team_busy, 0);
    return err;
  }
  bool coarse = o->coarse_factor > 1;
  double t0 = i2m_wtime();
  if (err == I2M_OK && coarse) { /* the coarse mesh: delta and the size bounds x the factor */
    i2m_refine_set_scale(r, o->coarse_factor);
    err = warm_up(r, T);
    if (err == I2M_OK) err = run_phase(&tm, false);
    i2m_refine_set_scale(r, 1.0);
  } else if (err == I2M_OK) {
    err = warm_up(r, T);
  }
  double t1 = i2m_wtime();
  if (err == I2M_OK) err = run_phase(&tm, coarse);
  for (int round = 0; err == I2M_OK && round < I2M_BRIDGE_ROUNDS; round++) { /* the component rule */
    bool more = false;
    err = bridge_round(r, &more);
    if (err == I2M_OK && more) err = run_phase(&tm, false);
    if (!more) break;
  }
  rep->coarse_seconds = coarse ? t1 - t0 : 0;
  rep->fine_seconds = i2m_wtime() - t1;
  report_fill(&tm, rep);
  team_free(&tm);
  atomic_store(&team_busy, 0);
  return err;
}

i2m_err_t i2m_threads_coarse(i2m_refine_t *r, const i2m_threads_opts_t *o, i2m_threads_report_t *rep)
{
  const int T = team_size(o->threads > 0 ? o->threads : i2m_threads_default());
  team_t tm;
  memset(rep, 0, sizeof *rep);
  I2M_CHECK(o->coarse_factor > 1, I2M_ERR_ARG, "the distributed level needs a coarse mesh: --coarse-factor must be above 1");
  I2M_CHECK(atomic_exchange(&team_busy, 1) == 0, I2M_ERR_UNSUPPORTED, "one parallel refinement at a time per process");
  i2m_err_t err = i2m_refine_set_workers(r, T);
  if (err == I2M_OK) err = team_init(&tm, r, T, o->pin);
  if (err != I2M_OK) {
    atomic_store(&team_busy, 0);
    return err;
  }
  const double t0 = i2m_wtime();
  rep->deterministic = o->deterministic;
  rep->depth = i2m_refine_depth(r);
  i2m_refine_set_scale(r, o->coarse_factor);
  if (o->deterministic) {
    err = i2m_refine_tiling_begin(r);
    if (err == I2M_OK) err = run_tiled(&tm, rep, false);
  } else {
    err = warm_up(r, T);
    if (err == I2M_OK) err = run_phase(&tm, false);
  }
  i2m_refine_set_scale(r, 1.0);
  if (err == I2M_OK) err = i2m_refine_octree_begin(r); /* every tet classified again into the octree's tiles */
  if (err == I2M_OK) err = i2m_refine_tiling_prepare_classify(r);
  if (err == I2M_OK) {
    job_t jb = {&tm, JOB_CLASSIFY, NULL, 0, 0};
    err = run_job(&tm, &jb);
  }
  if (err == I2M_OK) err = i2m_refine_tiling_collect(r);
  rep->coarse_seconds = i2m_wtime() - t0;
  report_fill(&tm, rep);
  team_free(&tm);
  atomic_store(&team_busy, 0);
  return err;
}

void i2m_threads_report_free(i2m_threads_report_t *rep) { i2m_free(&rep->thread); }

i2m_err_t i2m_threads_perturb_slivers(i2m_refine_t *r, const i2m_threads_opts_t *o, double bound,
                                      i2m_sliver_stats_t *st)
{
  const int T = i2m_refine_nworkers(r); /* (worker k runs on thread k) */
  if (T <= 1) return i2m_refine_perturb_slivers(r, bound, st);
  I2M_CHECK(atomic_exchange(&team_busy, 1) == 0, I2M_ERR_UNSUPPORTED, "one parallel refinement at a time per process");
  team_t tm;
  i2m_err_t err = team_init(&tm, r, T, o->pin);
  if (err == I2M_OK) err = i2m_refine_slivers_begin(r, bound);
  int64_t phases = 0;
  if (err == I2M_OK) err = tiled_rounds(&tm, &SLIVER_TILES, &phases);
  const i2m_err_t end = i2m_refine_slivers_end(r, st);
  team_free(&tm);
  atomic_store(&team_busy, 0);
  return err != I2M_OK ? err : end;
}
