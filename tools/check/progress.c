/* i2m-check: progress lines of the long phases on stderr (i2m_progress_t of the base layer:
 * "phase: N of TOTAL unit (P%), rate, elapsed, about S s left"), at most one line per phase
 * every ck_progress_set_interval() seconds (2 by default), and only at log level INFO
 * (i2m-check --quiet lowers it).  Loops run by OpenMP threads add their work per chunk to an
 * atomic counter; thread 0 alone prints. */
#include "check.h"

#ifdef _OPENMP
#include <omp.h>
#endif

static double progress_interval = 2.0;

void ck_progress_set_interval(double seconds) { progress_interval = seconds; }

void ck_progress_begin(ck_progress_t *p, const char *phase, const char *unit, int64_t total)
{
  i2m_progress_begin_total(&p->p, phase, unit, total);
  p->p.interval = progress_interval;
  atomic_init(&p->done, 0);
}

void ck_progress_add(ck_progress_t *p, int64_t n)
{
  const int64_t done = atomic_fetch_add_explicit(&p->done, n, memory_order_relaxed) + n;
#ifdef _OPENMP
  if (omp_get_thread_num() != 0) return;
#endif
  i2m_progress_update(&p->p, done);
}

void ck_progress_set(ck_progress_t *p, int64_t done)
{
  atomic_store_explicit(&p->done, done, memory_order_relaxed);
}

void ck_progress_to(ck_progress_t *p, int64_t done)
{
  ck_progress_set(p, done);
  i2m_progress_update(&p->p, done);
}

void ck_progress_end(ck_progress_t *p)
{
  i2m_progress_end(&p->p, atomic_load_explicit(&p->done, memory_order_relaxed));
}
