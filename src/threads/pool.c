/* Threads layer: the worker pool of the nested master-worker model (hybrid paper, Fig. 1a).
 *
 * One OpenMP parallel region of T + 1 threads: thread 0, the one that initialised MPI, runs the
 * caller's master function (it alone talks MPI: MPI_THREAD_FUNNELED), and threads 1..T are the
 * workers, which run the jobs the master starts: tiles to refine (each by one worker, taken in
 * turn), a tile's wide task, a reclassification of every tet, tiles of the sliver
 * perturbation.  The master starts a job and goes on polling; it sees the end of the job
 * through an atomic flag.  Jobs never grow the mesh's arrays (the tiles' slots are granted
 * before), so the master may read tiles that no job touches (to send them) meanwhile.
 *
 * Synchronisation is a pthread mutex and condition variable plus C11 atomics, which
 * ThreadSanitizer sees (as in team.c). */
#include <omp.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>

#include "threads_impl.h"

struct i2m_pool {
  i2m_refine_t *r;
  int T;
  pthread_mutex_t mu;
  pthread_cond_t cv;
  /* under mu */
  uint64_t gen;           /* job number: a worker runs each job once */
  i2m_pool_job_t job;
  int running;            /* workers still in the job */
  bool quit;
  i2m_err_t err;
  char errmsg[512];
  /* lock-free */
  _Atomic uint32_t next;  /* the next tile of the job */
  _Atomic int finished;   /* the job is over (read by the master while it polls) */
  _Atomic int started;    /* workers that entered the region */
  i2m_thread_figures_t *fig; /* [T] */
  i2m_pinning_t *pin;
  int pin_offset;
};

static _Atomic(i2m_pool_t *) active_pool;

static void job_fail(i2m_pool_t *p, i2m_err_t err)
{
  pthread_mutex_lock(&p->mu);
  if (p->err == I2M_OK) {
    p->err = err;
    snprintf(p->errmsg, sizeof p->errmsg, "%s", i2m_error_message());
  }
  pthread_mutex_unlock(&p->mu);
}

/* Worker k's part of the job. */
static i2m_err_t job_part(i2m_pool_t *p, const i2m_pool_job_t *jb, int k)
{
  i2m_refine_t *r = p->r;
  switch (jb->kind) {
  case I2M_POOL_TILES:
  case I2M_POOL_SLIVERS:
    for (;;) {
      const uint32_t i = atomic_fetch_add_explicit(&p->next, 1, memory_order_relaxed);
      if (i >= jb->ntiles) return I2M_OK;
      i2m_refine_stats_t before, after;
      i2m_refine_worker_stats(r, k, &before);
      I2M_CALL(jb->kind == I2M_POOL_TILES ? i2m_refine_tile_run(r, k, jb->tiles[i]) : i2m_refine_tile_slivers(r, k, jb->tiles[i]));
      i2m_refine_worker_stats(r, k, &after);
      if (jb->created) jb->created[i] = after.tets_created - before.tets_created;
    }
  case I2M_POOL_WIDE:
    return k == 0 && jb->ntiles ? i2m_refine_tile_run_wide(r, 0, jb->tiles[0]) : I2M_OK;
  case I2M_POOL_CLASSIFY:
    return i2m_refine_tiling_classify(r, k, p->T);
  default:
    return I2M_OK;
  }
}

static void worker_loop(i2m_pool_t *p, int k)
{
  uint64_t seen = 0;
  if (p->pin && p->fig[k].core == -2) p->fig[k].core = pinning_bind_thread(p->pin, p->pin_offset + k);
  for (;;) {
    pthread_mutex_lock(&p->mu);
    while (p->gen == seen && !p->quit) pthread_cond_wait(&p->cv, &p->mu);
    if (p->quit) {
      pthread_mutex_unlock(&p->mu);
      return;
    }
    seen = p->gen;
    const i2m_pool_job_t jb = p->job;
    pthread_mutex_unlock(&p->mu);
    const double t0 = i2m_wtime();
    const i2m_err_t err = job_part(p, &jb, k);
    p->fig[k].busy_seconds += i2m_wtime() - t0;
    if (err != I2M_OK) job_fail(p, err);
    pthread_mutex_lock(&p->mu);
    if (--p->running == 0) atomic_store_explicit(&p->finished, 1, memory_order_release);
    pthread_mutex_unlock(&p->mu);
  }
}

void i2m_pool_start(i2m_pool_t *p, const i2m_pool_job_t *job)
{
  pthread_mutex_lock(&p->mu);
  p->job = *job;
  p->err = I2M_OK;
  p->running = p->T;
  atomic_store_explicit(&p->next, 0, memory_order_relaxed);
  atomic_store_explicit(&p->finished, 0, memory_order_relaxed);
  p->gen++;
  pthread_cond_broadcast(&p->cv);
  pthread_mutex_unlock(&p->mu);
}

bool i2m_pool_finished(i2m_pool_t *p, i2m_err_t *err)
{
  if (!atomic_load_explicit(&p->finished, memory_order_acquire)) return false;
  pthread_mutex_lock(&p->mu); /* (the result, written under the mutex) */
  *err = p->err == I2M_OK ? I2M_OK : i2m_error_set(p->err, __FILE__, __LINE__, "%s", p->errmsg);
  pthread_mutex_unlock(&p->mu);
  return true;
}

i2m_err_t i2m_pool_run(i2m_pool_t *p, const i2m_pool_job_t *job)
{
  i2m_err_t err;
  i2m_pool_start(p, job);
  while (!i2m_pool_finished(p, &err)) sched_yield();
  return err;
}

int i2m_pool_threads(const i2m_pool_t *p) { return p->T; }

typedef struct {
  i2m_pool_t *pool;
  i2m_err_t (*master)(void *, i2m_pool_t *);
  void *ctx;
  i2m_err_t result;
  char msg[1024];
} region_t;

static _Atomic(region_t *) active_region;

/* Every thread of the region: the master (thread 0) or a worker. */
static void region_thread(void)
{
  region_t *rg = atomic_load_explicit(&active_region, memory_order_acquire);
  i2m_pool_t *p = rg->pool;
  const int id = omp_get_thread_num();
  if (id > 0) {
    atomic_fetch_add_explicit(&p->started, 1, memory_order_release);
    worker_loop(p, id - 1);
    return;
  }
  /* The master is no worker: it runs on any core of the process.  (It is the main thread, which
   * the coarse phase's team bound to worker 0's core: there it had to wait for that worker's
   * time slice, and another rank's requests waited a median 2.5-3 ms for it.) */
  pinning_float_thread(p->pin);
  while (atomic_load_explicit(&p->started, memory_order_acquire) < p->T) sched_yield();
  rg->result = rg->master(rg->ctx, p);
  if (rg->result != I2M_OK) snprintf(rg->msg, sizeof rg->msg, "%s", i2m_error_message());
  pthread_mutex_lock(&p->mu);
  p->quit = true;
  pthread_cond_broadcast(&p->cv);
  pthread_mutex_unlock(&p->mu);
}

i2m_err_t i2m_threads_serve(i2m_refine_t *r, const i2m_threads_opts_t *o, int pin_offset,
                            i2m_err_t (*master)(void *ctx, i2m_pool_t *pool), void *ctx, i2m_threads_report_t *rep)
{
  const int T = o->threads > 0 ? o->threads : i2m_threads_default();
  i2m_pool_t p;
  memset(&p, 0, sizeof p);
  memset(rep, 0, sizeof *rep);
  p.r = r;
  p.T = T;
  p.pin_offset = pin_offset;
  if (i2m_refine_nworkers(r) != T) I2M_CALL(i2m_refine_set_workers(r, T));
  I2M_CALL(i2m_calloc((size_t)T, sizeof *p.fig, &p.fig));
  for (int k = 0; k < T; k++) p.fig[k].core = o->pin ? -2 : -1;
  p.pin = o->pin ? pinning_open() : NULL;
  pthread_mutex_init(&p.mu, NULL);
  pthread_cond_init(&p.cv, NULL);
  region_t rg = {&p, master, ctx, I2M_OK, ""};
  atomic_store_explicit(&active_region, &rg, memory_order_release);
  atomic_store_explicit(&active_pool, &p, memory_order_release);
  omp_set_dynamic(0);
  I2M_OMP(omp parallel num_threads(T + 1))
  region_thread();
  atomic_store_explicit(&active_region, NULL, memory_order_relaxed);
  atomic_store_explicit(&active_pool, NULL, memory_order_relaxed);
  rep->threads = T;
  rep->thread = p.fig;
  int bound = 0;
  for (int k = 0; k < T; k++) {
    i2m_refine_stats_t s;
    i2m_refine_worker_stats(r, k, &s);
    rep->thread[k].insertions = s.insertions;
    rep->thread[k].removals = s.removals;
    bound += rep->thread[k].core >= 0;
  }
  rep->pinned = bound == T;
  if (!p.pin) snprintf(rep->binding, sizeof rep->binding, "not bound (--no-pin)");
  else if (rep->pinned) snprintf(rep->binding, sizeof rep->binding, "worker threads bound to cores from %d (hwloc)", pin_offset);
  else snprintf(rep->binding, sizeof rep->binding, "binding failed; threads float");
  pinning_close(p.pin);
  pthread_mutex_destroy(&p.mu);
  pthread_cond_destroy(&p.cv);
  if (rg.result != I2M_OK) return i2m_error_set(rg.result, __FILE__, __LINE__, "%s", rg.msg);
  return I2M_OK;
}
