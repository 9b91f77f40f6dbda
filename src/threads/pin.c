/* Threads layer: the cores a process may use and binding threads to them (hwloc). */
#include <hwloc.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>

#include "threads_impl.h"

struct i2m_pinning {
  hwloc_topology_t topo;
  hwloc_bitmap_t allowed;
  int ncores;
};

static int count_cores(hwloc_topology_t topo, hwloc_bitmap_t allowed)
{
  int n = hwloc_get_nbobjs_inside_cpuset_by_type(topo, allowed, HWLOC_OBJ_CORE);
  if (n <= 0) n = hwloc_get_nbobjs_inside_cpuset_by_type(topo, allowed, HWLOC_OBJ_PU);
  return n;
}

/* The cores the process was given, as the first pinning found them: later the process's own
 * threads are bound (the main thread too), and their bindings are not what the launcher gave. */
static pthread_mutex_t given_lock = PTHREAD_MUTEX_INITIALIZER;
static hwloc_bitmap_t given;

i2m_pinning_t *pinning_open(void)
{
  i2m_pinning_t *p = NULL;
  if (i2m_calloc(1, sizeof *p, &p) != I2M_OK) return NULL;
  if (hwloc_topology_init(&p->topo) != 0) {
    i2m_free(&p);
    return NULL;
  }
  if (hwloc_topology_load(p->topo) != 0) {
    hwloc_topology_destroy(p->topo);
    i2m_free(&p);
    return NULL;
  }
  p->allowed = hwloc_bitmap_alloc();
  pthread_mutex_lock(&given_lock);
  if (!given && (given = hwloc_bitmap_alloc()) && hwloc_get_cpubind(p->topo, given, HWLOC_CPUBIND_PROCESS) != 0)
    hwloc_bitmap_copy(given, hwloc_topology_get_allowed_cpuset(p->topo));
  hwloc_bitmap_copy(p->allowed, given ? given : hwloc_topology_get_allowed_cpuset(p->topo));
  pthread_mutex_unlock(&given_lock);
  p->ncores = count_cores(p->topo, p->allowed);
  if (p->ncores <= 0) p->ncores = 1;
  return p;
}

void pinning_close(i2m_pinning_t *p)
{
  if (!p) return;
  hwloc_bitmap_free(p->allowed);
  hwloc_topology_destroy(p->topo);
  i2m_free(&p);
}

int pinning_cores(const i2m_pinning_t *p) { return p ? p->ncores : 1; }

int pinning_bind_thread(i2m_pinning_t *p, int k)
{
  if (!p) return -1;
  int core = k % p->ncores;
  hwloc_obj_t obj = hwloc_get_obj_inside_cpuset_by_type(p->topo, p->allowed, HWLOC_OBJ_CORE, (unsigned)core);
  if (!obj) obj = hwloc_get_obj_inside_cpuset_by_type(p->topo, p->allowed, HWLOC_OBJ_PU, (unsigned)core);
  if (!obj) return -1;
  hwloc_bitmap_t set = hwloc_bitmap_dup(obj->cpuset);
  hwloc_bitmap_singlify(set); /* one PU of the core: no migration between hyperthreads */
  int ok = hwloc_set_cpubind(p->topo, set, HWLOC_CPUBIND_THREAD) == 0;
  hwloc_bitmap_free(set);
  return ok ? core : -1;
}

void pinning_float_thread(i2m_pinning_t *p)
{
  if (p) (void)hwloc_set_cpubind(p->topo, p->allowed, HWLOC_CPUBIND_THREAD);
}

int i2m_threads_available(void)
{
  i2m_pinning_t *p = pinning_open();
  int n = pinning_cores(p);
  pinning_close(p);
  return n;
}

int i2m_threads_default(void)
{
  const char *env = getenv("OMP_NUM_THREADS");
  if (env) { /* "4" or a nesting list "4,2": the first level is ours */
    char *end = NULL;
    long n = strtol(env, &end, 10);
    if (end != env && n >= 1 && n <= 4096) return (int)n;
  }
  return i2m_threads_available();
}
