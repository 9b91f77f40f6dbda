/* Base layer: wall-clock timer and resident-memory figures (POSIX). */
#define _POSIX_C_SOURCE 200809L
#include "i2m/base.h"

#include <stdio.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

double i2m_wtime(void)
{
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

size_t i2m_peak_rss_bytes(void)
{
  struct rusage ru;
  if (getrusage(RUSAGE_SELF, &ru) != 0) return 0;
#ifdef __APPLE__
  return (size_t)ru.ru_maxrss; /* bytes on macOS */
#else
  return (size_t)ru.ru_maxrss * 1024u; /* kilobytes on Linux and the BSDs */
#endif
}

size_t i2m_current_rss_bytes(void)
{
  FILE *f = fopen("/proc/self/statm", "r");
  if (!f) return 0;
  long pages_total = 0, pages_resident = 0;
  int ok = fscanf(f, "%ld %ld", &pages_total, &pages_resident) == 2;
  fclose(f);
  if (!ok) return 0;
  return (size_t)pages_resident * (size_t)sysconf(_SC_PAGESIZE);
}

double i2m_memory_limit_bytes(void)
{
  double limit = 0;
#if defined(_SC_PHYS_PAGES) && defined(_SC_PAGESIZE)
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  if (pages > 0 && page > 0) limit = (double)pages * (double)page;
#endif
  static const int which[] = {RLIMIT_AS, RLIMIT_DATA};
  for (size_t i = 0; i < sizeof which / sizeof *which; i++) {
    struct rlimit rl;
    if (getrlimit(which[i], &rl) == 0 && rl.rlim_cur != RLIM_INFINITY && (limit == 0 || (double)rl.rlim_cur < limit))
      limit = (double)rl.rlim_cur;
  }
  return limit;
}
