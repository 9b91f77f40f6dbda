/* Delaunay layer: the validity check (orientation, adjacency, empty circumspheres under the
 * perturbation, vertex hints) and an order-independent checksum of the tetrahedralization. */
#include "dt_impl.h"

#include <stdlib.h>

static i2m_err_t check_adjacency(const i2m_dt_t *dt, uint32_t t)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  for (uint32_t i = 0; i < 4; i++) {
    uint32_t n = dt->tn[4 * t + i];
    if (n == I2M_DT_REMOTE) continue; /* another rank's side */
    if (n == I2M_DT_NONE) {
      int nbox = 0;
      for (uint32_t j = 0; j < 4; j++) nbox += j != i && dt->vkind[v[j]] == I2M_VK_BOX;
      I2M_CHECK(nbox == 3, I2M_ERR_INTERNAL, "tet %u face %u has no neighbour but is not on the box", t, i);
      continue;
    }
    uint32_t u = n >> 2, j = n & 3;
    I2M_CHECK(u < i2m_dt_ntets_slots(dt) && i2m_dt_alive(dt, u), I2M_ERR_INTERNAL,
              "tet %u face %u: neighbour %u is dead or out of range", t, i, u);
    I2M_CHECK(dt->tn[4 * u + j] == 4 * t + i, I2M_ERR_INTERNAL, "tet %u face %u: adjacency not symmetric", t, i);
    /* the shared face: same three vertices, and u's opposite vertex is not in t */
    int shared = 0;
    for (uint32_t a = 0; a < 4; a++)
      for (uint32_t b = 0; b < 4; b++)
        if (a != i && b != j && v[a] == dt->tv[4 * u + b]) shared++;
    I2M_CHECK(shared == 3, I2M_ERR_INTERNAL, "tet %u face %u and tet %u face %u differ", t, i, u, j);
  }
  return I2M_OK;
}

static i2m_err_t check_tet(const i2m_dt_t *dt, uint32_t t, bool check_delaunay)
{
  const uint32_t *v = dt->tv + 4 * (size_t)t;
  uint32_t nv = i2m_dt_nverts_slots(dt);
  for (int i = 0; i < 4; i++) {
    I2M_CHECK(v[i] < nv && dt->vkind[v[i]] != I2M_VK_DEAD, I2M_ERR_INTERNAL, "tet %u uses a dead vertex %u", t, v[i]);
    for (int j = i + 1; j < 4; j++) I2M_CHECK(v[i] != v[j], I2M_ERR_INTERNAL, "tet %u repeats vertex %u", t, v[i]);
  }
  int o = i2m_orient3d(i2m_dt_xyz(dt, v[0]), i2m_dt_xyz(dt, v[1]), i2m_dt_xyz(dt, v[2]), i2m_dt_xyz(dt, v[3]));
  I2M_CHECK(o > 0, I2M_ERR_INTERNAL, "tet %u (%u %u %u %u) is %s", t, v[0], v[1], v[2], v[3],
            o == 0 ? "flat" : "inverted");
  I2M_CALL(check_adjacency(dt, t));
  if (!check_delaunay) return I2M_OK;
  for (uint32_t i = 0; i < 4; i++) {
    uint32_t n = dt->tn[4 * t + i];
    if (n >= I2M_DT_REMOTE || (n >> 2) < t) continue; /* each face once */
    uint32_t w = dt->tv[4 * (n >> 2) + (n & 3)];
    I2M_CHECK(tet_insphere(dt, v, i2m_dt_xyz(dt, w), i2m_dt_gid(dt, w)) < 0, I2M_ERR_INTERNAL,
              "tet %u is not Delaunay: vertex %u of its neighbour across face %u is inside its circumsphere", t, w, i);
  }
  return I2M_OK;
}

i2m_err_t i2m_dt_check(const i2m_dt_t *dt, bool check_delaunay)
{
  uint32_t nt = i2m_dt_ntets_slots(dt), nv = i2m_dt_nverts_slots(dt);
  for (uint32_t t = 0; t < nt; t++)
    if (i2m_dt_alive(dt, t)) I2M_CALL(check_tet(dt, t, check_delaunay));
  for (uint32_t v = 0; v < nv; v++) {
    if (dt->vkind[v] == I2M_VK_DEAD) continue;
    uint32_t t = dt->vtet[v];
    if (v < 8 && (t >= nt || !i2m_dt_alive(dt, t) ||
                  (dt->tv[4 * (size_t)t] != v && dt->tv[4 * (size_t)t + 1] != v && dt->tv[4 * (size_t)t + 2] != v &&
                   dt->tv[4 * (size_t)t + 3] != v)))
      continue; /* a box corner that perhaps no local tet uses (the dist layer: another rank's) */
    I2M_CHECK(t < nt && i2m_dt_alive(dt, t), I2M_ERR_INTERNAL, "vertex %u: its tet hint %u is dead", v, t);
    const uint32_t *tv = dt->tv + 4 * (size_t)t;
    I2M_CHECK(tv[0] == v || tv[1] == v || tv[2] == v || tv[3] == v, I2M_ERR_INTERNAL,
              "vertex %u: its tet hint %u does not contain it", v, t);
  }
  return I2M_OK;
}

static uint64_t mix64(uint64_t z)
{
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

uint64_t i2m_dt_checksum(const i2m_dt_t *dt, int64_t *ntets)
{
  uint64_t sum = 0; /* a sum modulo 2^64: the same in any order, on any number of threads */
  int64_t n = 0;
  const int64_t nt = i2m_dt_ntets_slots(dt), nv = i2m_dt_nverts_slots(dt);
  /* the ids side by side (8 bytes a vertex instead of 32): the random reads hit the cache more */
  i2m_gidx_t *gid = malloc((size_t)(nv > 0 ? nv : 1) * sizeof *gid);
  if (gid) {
    I2M_OMP(omp parallel for schedule(static))
    for (int64_t v = 0; v < nv; v++) gid[v] = i2m_dt_gid(dt, (uint32_t)v);
  }
  I2M_OMP(omp parallel for reduction(+ : sum, n) schedule(static))
  for (int64_t t = 0; t < nt; t++) {
    if (!i2m_dt_alive(dt, (uint32_t)t)) continue;
    i2m_gidx_t g[4];
    const uint32_t *tv = dt->tv + 4 * (size_t)t;
    for (int i = 0; i < 4; i++) g[i] = gid ? gid[tv[i]] : i2m_dt_gid(dt, tv[i]);
    for (int i = 1; i < 4; i++) /* insertion sort of four ids */
      for (int j = i; j > 0 && g[j - 1] > g[j]; j--) {
        i2m_gidx_t x = g[j];
        g[j] = g[j - 1];
        g[j - 1] = x;
      }
    uint64_t h = 0x12345678ull;
    for (int i = 0; i < 4; i++) h = mix64(h ^ (uint64_t)g[i]);
    sum += h;
    n++;
  }
  free(gid);
  if (ntets) *ntets = n;
  return sum;
}
