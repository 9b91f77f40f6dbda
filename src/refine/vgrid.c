/* Refine layer: a spatial hash of vertices (cells of side h, each a linked list through
 * next[]), with a tag per vertex.  Two are used: the surface vertices tagged with the
 * interface patch they sample (R1's spacing test; append-only and lock-free) and the free
 * vertices close to an interface (the candidates of R7's removals; striped spinlocks). */
#include "refine_impl.h"

#include <sched.h>
#include <stdlib.h>
#include <string.h>

#define VGRID_MAX_CELLS (1u << 23)

static uint32_t cell_axis(const vgrid_t *g, int a, double x)
{
  double u = (x - g->origin[a]) * g->inv_h; /* clamped, then truncated: no floor() call */
  return !(u >= 0) ? 0 : u >= (double)g->nc[a] ? g->nc[a] - 1 : (uint32_t)u;
}

static uint32_t cell_of(const vgrid_t *g, const double p[3])
{
  return (cell_axis(g, 2, p[2]) * g->nc[1] + cell_axis(g, 1, p[1])) * g->nc[0] + cell_axis(g, 0, p[0]);
}

static void stripe_lock(const vgrid_t *g, uint32_t cell)
{
  if (!g->stripe) return;
  _Atomic uint32_t *L = &g->stripe[cell % VGRID_STRIPES];
  for (;;) {
    uint32_t expected = 0;
    if (atomic_compare_exchange_weak_explicit(L, &expected, 1, memory_order_acquire, memory_order_relaxed)) return;
    while (atomic_load_explicit(L, memory_order_relaxed)) sched_yield();
  }
}

static void stripe_unlock(const vgrid_t *g, uint32_t cell)
{
  if (g->stripe) atomic_store_explicit(&g->stripe[cell % VGRID_STRIPES], 0, memory_order_release);
}

i2m_err_t vgrid_enable_locks(vgrid_t *g)
{
  if (g->stripe) return I2M_OK;
  I2M_CALL(i2m_malloc(VGRID_STRIPES, sizeof *g->stripe, &g->stripe));
  for (uint32_t k = 0; k < VGRID_STRIPES; k++) atomic_init(&g->stripe[k], 0);
  return I2M_OK;
}

i2m_err_t vgrid_init(vgrid_t *g, const double lo[3], const double hi[3], double h)
{
  memset(g, 0, sizeof *g);
  I2M_CHECK(h > 0 && isfinite(h), I2M_ERR_INTERNAL, "a grid of cells of side %g", h);
  for (;;) { /* cells of side h over [lo - h, hi + h], coarser if that makes too many */
    double n = 1, m[3]; /* (counted in doubles: a tiny h must not overflow them) */
    for (int a = 0; a < 3; a++) {
      m[a] = fmax(1.0, ceil((hi[a] - lo[a] + 2 * h) / h));
      n *= m[a];
    }
    if (n <= (double)VGRID_MAX_CELLS) {
      for (int a = 0; a < 3; a++) {
        g->origin[a] = lo[a] - h;
        g->nc[a] = (uint32_t)m[a];
      }
      g->h = h;
      g->inv_h = 1.0 / h;
      g->ncells = (uint32_t)n;
      break;
    }
    h *= 1.26;
  }
  I2M_CALL(i2m_malloc(g->ncells, sizeof *g->head, &g->head));
  for (uint32_t c = 0; c < g->ncells; c++) atomic_init(&g->head[c], I2M_DT_NONE);
  return I2M_OK;
}

void vgrid_free(vgrid_t *g)
{
  free((void *)g->head);
  free((void *)g->next);
  free((void *)g->stripe);
  i2m_free(&g->tag);
  memset(g, 0, sizeof *g);
}

i2m_err_t vgrid_reserve(vgrid_t *g, uint32_t cap)
{
  if (cap <= g->cap_next) return I2M_OK;
  I2M_CALL(i2m_realloc_large(cap, sizeof *g->next, &g->next));
  I2M_CALL(i2m_realloc_large(cap, sizeof *g->tag, &g->tag));
  for (uint32_t v = g->cap_next; v < cap; v++) atomic_init(&g->next[v], I2M_DT_NONE);
  memset(g->tag + g->cap_next, 0, (cap - g->cap_next) * sizeof *g->tag);
  g->cap_next = cap;
  return I2M_OK;
}

i2m_err_t vgrid_insert(vgrid_t *g, const i2m_dt_t *dt, uint32_t v, uint32_t tag)
{
  if (v >= g->cap_next) I2M_CALL(vgrid_reserve(g, dt->cap_v > v ? dt->cap_v : v + 1)); /* sequential only */
  uint32_t c = cell_of(g, i2m_dt_xyz(dt, v));
  g->tag[v] = tag;
  stripe_lock(g, c);
  uint32_t head = atomic_load_explicit(&g->head[c], memory_order_relaxed);
  do {
    atomic_store_explicit(&g->next[v], head, memory_order_relaxed);
  } while (!atomic_compare_exchange_weak_explicit(&g->head[c], &head, v, memory_order_release, memory_order_relaxed));
  stripe_unlock(g, c);
  return I2M_OK;
}

void vgrid_remove(vgrid_t *g, const i2m_dt_t *dt, uint32_t v)
{
  uint32_t c = cell_of(g, i2m_dt_xyz(dt, v));
  stripe_lock(g, c);
  _Atomic uint32_t *link = &g->head[c];
  for (uint32_t u; (u = atomic_load_explicit(link, memory_order_relaxed)) != I2M_DT_NONE; link = &g->next[u])
    if (u == v) {
      atomic_store_explicit(link, atomic_load_explicit(&g->next[v], memory_order_relaxed), memory_order_relaxed);
      g->tag[v] = 0;
      break;
    }
  stripe_unlock(g, c);
}

/* Calls fn(arg, v) for every vertex of the cells that meet the box [z - rad, z + rad] whose
 * distance to z is below rad; stops early when fn returns true.  Returns true if it did. */
static bool vgrid_scan(const vgrid_t *g, const i2m_dt_t *dt, const double z[3], double rad,
                       bool (*fn)(void *, uint32_t), void *arg)
{
  uint32_t c0[3], c1[3];
  for (int a = 0; a < 3; a++) {
    c0[a] = cell_axis(g, a, z[a] - rad);
    c1[a] = cell_axis(g, a, z[a] + rad);
  }
  double r2 = rad * rad;
  for (uint32_t k = c0[2]; k <= c1[2]; k++)
    for (uint32_t j = c0[1]; j <= c1[1]; j++)
      for (uint32_t i = c0[0]; i <= c1[0]; i++) {
        uint32_t c = (k * g->nc[1] + j) * g->nc[0] + i;
        bool stop = false;
        stripe_lock(g, c);
        for (uint32_t v = atomic_load_explicit(&g->head[c], memory_order_acquire); v != I2M_DT_NONE && !stop;
             v = atomic_load_explicit(&g->next[v], memory_order_relaxed))
          stop = i2m_dist2(i2m_dt_xyz(dt, v), z) < r2 && fn(arg, v);
        stripe_unlock(g, c);
        if (stop) return true;
      }
  return false;
}

typedef struct {
  const vgrid_t *g;
  uint32_t tag;
} tag_match_t;

static bool has_tag(void *arg, uint32_t v)
{
  const tag_match_t *m = arg;
  return m->g->tag[v] == m->tag;
}

bool vgrid_has_within(const vgrid_t *g, const i2m_dt_t *dt, const double z[3], double rad, uint32_t tag)
{
  tag_match_t m = {g, tag};
  return vgrid_scan(g, dt, z, rad, has_tag, &m);
}

typedef struct {
  const i2m_dt_t *dt;
  pending_t **out;
  uint32_t *n, *cap;
  bool failed;
} collect_t;

static bool collect_one(void *arg, uint32_t v)
{
  collect_t *c = arg;
  if (*c->n == *c->cap) {
    uint32_t cap = *c->cap ? 2 * *c->cap : 64;
    if (i2m_realloc(cap, sizeof **c->out, c->out) != I2M_OK) {
      c->failed = true;
      return true;
    }
    *c->cap = cap;
  }
  (*c->out)[*c->n].v = v;
  (*c->out)[*c->n].gid = i2m_dt_gid(c->dt, v); /* read under the cell's lock: v is not recycled */
  (*c->n)++;
  return false;
}

i2m_err_t vgrid_collect_within(const vgrid_t *g, const i2m_dt_t *dt, const double z[3], double rad,
                               pending_t **out, uint32_t *n, uint32_t *cap)
{
  collect_t c = {dt, out, n, cap, false};
  vgrid_scan(g, dt, z, rad, collect_one, &c);
  I2M_CHECK(!c.failed, I2M_ERR_MEMORY, "out of memory collecting vertices near a surface point");
  return I2M_OK;
}
