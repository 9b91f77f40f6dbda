/* Micro-benchmark of the robust predicates (geometry layer 1): ns per call of orient3d,
 * insphere and insphere_sos on
 *   - random points in the unit cube (the floating-point filter decides),
 *   - lattice points 0..3 (a mix: the filter, plus the exact path for the many exact zeros),
 *   - cospherical lattice points (insphere always 0: exact path on exact differences, then
 *     the SoS cofactors),
 *   - points on the plane x = y with full-mantissa coordinates (always 0, inexact
 *     differences: the exact path on the original coordinates; for insphere_sos the worst
 *     case, five coplanar points: exact insphere plus five exact orient3d).
 * The naive i2m_*_fast doubles are timed on the first case for comparison.
 * Each figure is the best of 5 runs, in process CPU time.  Prints one line per case; not a test.  Usage: bench_predicates [calls_millions] */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "i2m/base.h"
#include "i2m/predicates.h"

#define NPTS 4096
#define NQ 8192

static uint64_t rng_state = 12345;
static uint64_t rng_next(void)
{
  uint64_t z = (rng_state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}
static double rng_unit(void) { return (double)(rng_next() >> 11) * 0x1p-53; }

typedef struct {
  double pts[NPTS][3];
  int q[NQ][5]; /* five distinct point indices per query */
} workload_t;

static void make_queries(workload_t *w, int npts)
{
  for (int i = 0; i < NQ; i++)
    for (int k = 0; k < 5; k++) {
      int again;
      do {
        w->q[i][k] = (int)(rng_next() % (uint64_t)npts);
        again = 0;
        for (int j = 0; j < k; j++) again |= w->q[i][j] == w->q[i][k];
      } while (again);
    }
}

typedef enum { P_ORIENT3D, P_INSPHERE, P_INSPHERE_SOS, P_ORIENT3D_FAST, P_INSPHERE_FAST } pred_t;

/* returns ns per call; *zeros = share of zero results */
static double run(const workload_t *w, pred_t which, long calls, double *zeros)
{
  long nz = 0, sum = 0;
  const clock_t t0 = clock(); /* CPU time: robust to a shared machine */
  for (long n = 0; n < calls;) {
    for (int i = 0; i < NQ && n < calls; i++, n++) {
      const int *q = w->q[i];
      const double *a = w->pts[q[0]], *b = w->pts[q[1]], *c = w->pts[q[2]], *d = w->pts[q[3]],
                   *e = w->pts[q[4]];
      int s;
      if (which == P_ORIENT3D) s = i2m_orient3d(a, b, c, d);
      else if (which == P_INSPHERE) s = i2m_insphere(a, b, c, d, e);
      else if (which == P_INSPHERE_SOS) s = i2m_insphere_sos(a, b, c, d, e, q[0], q[1], q[2], q[3], q[4]);
      else if (which == P_ORIENT3D_FAST) s = i2m_orient3d_fast(a, b, c, d) > 0.0;
      else s = i2m_insphere_fast(a, b, c, d, e) > 0.0;
      nz += s == 0;
      sum += s;
    }
  }
  const double t = (double)(clock() - t0) / CLOCKS_PER_SEC;
  *zeros = (double)nz / (double)calls;
  if (sum == 0x7fffffff) printf("(unlikely)\n"); /* keeps the calls alive */
  return 1e9 * t / (double)calls;
}

static void report(const char *name, const workload_t *w, long calls, int with_fast)
{
  static const char *pname[5] = {"orient3d", "insphere", "insphere_sos", "orient3d_fast", "insphere_fast"};
  for (int p = 0; p < (with_fast ? 5 : 3); p++) {
    double z, ns = 1e30;
    run(w, (pred_t)p, calls / 10 + 1, &z); /* warm-up */
    for (int rep = 0; rep < 5; rep++) { /* best of 5: the machine may be shared */
      const double t = run(w, (pred_t)p, calls / 5 + 1, &z);
      ns = t < ns ? t : ns;
    }
    printf("  %-34s %-13s %9.1f ns/call   (%5.1f%% zero)\n", name, pname[p], ns, 100.0 * z);
  }
}

int main(int argc, char **argv)
{
  const double millions = argc > 1 ? atof(argv[1]) : 4.0;
  const long calls = (long)(millions * 1e6);
  workload_t *w = malloc(sizeof *w);
  if (!w) return 1;
  printf("bench_predicates: %ld calls per filter case (ns per call, process CPU time)\n", calls);

  for (int i = 0; i < NPTS; i++)
    for (int k = 0; k < 3; k++) w->pts[i][k] = rng_unit();
  make_queries(w, NPTS);
  report("random unit cube (filter)", w, calls, 1);

  for (int i = 0; i < 64; i++)
    for (int k = 0; k < 3; k++) w->pts[i][k] = (double)((i >> (2 * k)) & 3);
  make_queries(w, 64);
  report("lattice 4x4x4 (filter + exact)", w, calls / 4, 0);

  /* the 30 lattice points of x^2 + y^2 + z^2 = 50 (all cospherical), centred at (7,3,5) */
  int n = 0;
  for (int x = -7; x <= 7; x++)
    for (int y = -7; y <= 7; y++)
      for (int z = -7; z <= 7; z++)
        if (x * x + y * y + z * z == 50 && n < NPTS) {
          w->pts[n][0] = 7 + x;
          w->pts[n][1] = 3 + y;
          w->pts[n][2] = 5 + z;
          n++;
        }
  make_queries(w, n);
  report("cospherical lattice (exact)", w, calls / 20, 0);

  for (int i = 0; i < NPTS; i++) {
    const double t = 1000.0 * rng_unit();
    w->pts[i][0] = t;
    w->pts[i][1] = t;
    w->pts[i][2] = 1000.0 * rng_unit();
  }
  make_queries(w, NPTS);
  report("plane x=y, inexact diffs (exact)", w, calls / 100, 0);
  free(w);
  return 0;
}
