/* Benchmark: Delaunay insertion throughput of the kernel on one thread (random points in
 * the unit cube, BRIO + Hilbert order) and peak bytes per tetrahedron.
 * Usage: bench_delaunay N [N ...] [--json FILE]    (prints a line per N) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "i2m/dt.h"

static uint64_t rng = 0x2545F4914F6CDD1Dull;
static double urand(void)
{
  rng ^= rng << 13;
  rng ^= rng >> 7;
  rng ^= rng << 17;
  return (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

typedef struct {
  long long n, ntets;
  double seconds, pts_per_s, tets_per_s, bytes_per_tet, rss_mb;
} result_t;

static int run(long long n, result_t *r)
{
  double *xyz = malloc(3 * (size_t)n * sizeof *xyz);
  if (!xyz) return 1;
  for (long long i = 0; i < 3 * n; i++) xyz[i] = urand();
  size_t rss0 = i2m_current_rss_bytes();
  double lo[3] = {-2, -2, -2}, hi[3] = {3, 3, 3};
  i2m_dt_t *dt = NULL;
  double t0 = i2m_wtime();
  if (i2m_dt_create(lo, hi, (uint32_t)n, 0, &dt) != I2M_OK ||
      i2m_dt_insert_points(dt, xyz, n, 8, 1, NULL, NULL) != I2M_OK) {
    fprintf(stderr, "bench_delaunay: %s\n", i2m_error_message());
    return 1;
  }
  double t1 = i2m_wtime();
  size_t rss1 = i2m_current_rss_bytes();
  r->n = n;
  r->ntets = i2m_dt_count_tets(dt);
  r->seconds = t1 - t0;
  r->pts_per_s = (double)n / r->seconds;
  r->tets_per_s = (double)r->ntets / r->seconds;
  /* memory of the triangulation and of the insertion's temporaries, per tet: RSS growth
   * over the run (the input points are excluded: they were resident before) */
  size_t peak = i2m_peak_rss_bytes();
  size_t grown = (peak > rss0 ? peak : rss1) - rss0;
  r->bytes_per_tet = (double)grown / (double)r->ntets;
  r->rss_mb = (double)peak / 1048576.0;
  i2m_dt_destroy(&dt);
  free(xyz);
  return 0;
}

int main(int argc, char **argv)
{
  const char *json = NULL;
  i2m_malloc_tune();
  if (getenv("I2M_DEBUG")) i2m_log_set_level(I2M_LOG_DEBUG);
  long long ns[8];
  int nn = 0;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--json") && i + 1 < argc) json = argv[++i];
    else if (nn < 8) ns[nn++] = atoll(argv[i]);
  }
  if (nn == 0) ns[nn++] = 1000000;
  result_t res[8];
  for (int k = 0; k < nn; k++) {
    if (run(ns[k], &res[k])) return 1;
    printf("delaunay 1 thread: %lld points -> %lld tets in %.3f s: %.3f M points/s, %.2f M tets/s, %.1f bytes/tet (peak RSS %.0f MB)\n",
           res[k].n, res[k].ntets, res[k].seconds, res[k].pts_per_s / 1e6, res[k].tets_per_s / 1e6,
           res[k].bytes_per_tet, res[k].rss_mb);
    fflush(stdout);
  }
  if (json) {
    FILE *f = fopen(json, "w");
    if (!f) {
      perror(json);
      return 1;
    }
    fprintf(f, "{\"benchmark\": \"delaunay_insertion\", \"threads\": 1, \"runs\": [");
    for (int k = 0; k < nn; k++)
      fprintf(f, "%s{\"points\": %lld, \"tets\": %lld, \"seconds\": %.4f, \"points_per_s\": %.0f, \"tets_per_s\": %.0f, \"bytes_per_tet\": %.1f}",
              k ? ", " : "", res[k].n, res[k].ntets, res[k].seconds, res[k].pts_per_s, res[k].tets_per_s, res[k].bytes_per_tet);
    fprintf(f, "], \"targets\": {\"points_per_s\": 850000, \"bytes_per_tet\": 80}}\n");
    fclose(f);
  }
  return 0;
}
