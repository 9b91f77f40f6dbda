/* Base layer: verbosity-controlled logging and progress lines on stderr. */
#include "i2m/base.h"

#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

static i2m_log_level_t log_level = I2M_LOG_INFO;
static char log_prefix[64];

void i2m_log_set_level(i2m_log_level_t level) { log_level = level; }
i2m_log_level_t i2m_log_get_level(void) { return log_level; }

void i2m_log_set_prefix(const char *prefix)
{
  snprintf(log_prefix, sizeof log_prefix, "%s", prefix ? prefix : "");
}

void i2m_log(i2m_log_level_t level, const char *fmt, ...)
{
  if (level > log_level) return;
  char line[1200];
  int n = snprintf(line, sizeof line, "%s", log_prefix);
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(line + n, sizeof line - (size_t)n, fmt, ap);
  va_end(ap);
  fprintf(stderr, "%s\n", line); /* one call: lines from threads do not interleave */
}

void i2m_progress_begin(i2m_progress_t *p, const char *phase, const char *unit)
{
  p->phase = phase;
  p->unit = unit;
  p->t_start = p->t_last = i2m_wtime();
  p->interval = 2.0;
  p->total = 0;
  p->done = 0;
  p->busy = 0;
}

void i2m_progress_begin_total(i2m_progress_t *p, const char *phase, const char *unit, int64_t total)
{
  i2m_progress_begin(p, phase, unit);
  p->total = total > 0 ? total : 0;
}

static void progress_print(const i2m_progress_t *p, int64_t count, double now, const char *tag)
{
  double dt = now - p->t_start;
  double rate = dt > 0 ? (double)count / dt : 0.0;
  if (p->total > 0 && !*tag && rate > 0) /* (the time left: at the rate so far) */
    i2m_info("%s: %lld of %lld %s (%.0f%%), %.3g %s/s, %.1f s, about %.0f s left", p->phase, (long long)count,
             (long long)p->total, p->unit, 100.0 * (double)count / (double)p->total, rate, p->unit, dt,
             (double)(p->total - count) / rate);
  else
    i2m_info("%s%s: %lld %s, %.3g %s/s, %.1f s", p->phase, tag, (long long)count, p->unit, rate, p->unit, dt);
}

void i2m_progress_update(i2m_progress_t *p, int64_t count)
{
  if (log_level < I2M_LOG_INFO) return;
  double now = i2m_wtime();
  if (now - p->t_last < p->interval) return;
  p->t_last = now;
  progress_print(p, count, now, "");
}

void i2m_progress_end(i2m_progress_t *p, int64_t count)
{
  double now = i2m_wtime();
  if (now - p->t_start >= p->interval) progress_print(p, count, now, " done");
}

void i2m_progress_add(i2m_progress_t *p, int64_t n)
{
  const int64_t done = atomic_fetch_add_explicit((_Atomic int64_t *)&p->done, n, memory_order_relaxed) + n;
  /* one thread at a time looks at the clock and prints; the others go on (a try-lock) */
  if (atomic_exchange_explicit((_Atomic int *)&p->busy, 1, memory_order_acquire)) return;
  i2m_progress_update(p, done);
  atomic_store_explicit((_Atomic int *)&p->busy, 0, memory_order_release);
}
