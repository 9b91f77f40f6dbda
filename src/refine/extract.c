/* Refine layer: extraction of the labelled mesh (REFERENCE §1.8): the tets whose
 * circumcentre is inside, labelled there; the interface triangles between different labels;
 * compacted vertices.  The mesher works
 * in world coordinates, so the tets keep the exact positive orientation the kernel gave.
 * Triangle orientation (include/i2m/tetmesh.h): the normal points from the higher label to
 * the lower one, the background ranking below every tissue: out of the meshed domain on the
 * outer boundary, the Medit / mmg / Gmsh convention. */
#include "refine_impl.h"

#include <string.h>

/* Face i of a positive tet with its outward normal (right-hand rule). */
static const int FACE_OUT[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

static int64_t neighbour_label(const i2m_refine_t *r, uint32_t t, int i)
{
  uint32_t n = r->dt->tn[4 * t + i];
  if (n == I2M_DT_REMOTE) return r->img->label_value[dist_ghost_label(r, t, i)]; /* (another rank's tet) */
  return n == I2M_DT_NONE ? 0 : r->img->label_value[tinfo(r->dt, n >> 2)->label];
}

/* The tet slots are cut into EXTRACT_CHUNKS fixed chunks: counted in parallel, offsets by
 * prefix sums, filled in parallel; the output does not depend on the number of threads. */
#define EXTRACT_CHUNKS 256

/* The number of tet slots in chunk c (for the progress line). */
static int64_t chunk_slots(const i2m_dt_t *dt, int c)
{
  const uint64_t n = i2m_dt_ntets_slots(dt);
  return (int64_t)(n * (uint64_t)(c + 1) / EXTRACT_CHUNKS - n * (uint64_t)c / EXTRACT_CHUNKS);
}

/* The interface faces of kept tet t to write (each once: from the side whose label ranks
 * lower, or from the only labelled side). */
static bool face_written_here(int64_t lt, int64_t lu)
{
  return lu != lt && (lu == 0 || i2m_label_ranks_below(lt, lu));
}

static int faces_to_write(const i2m_refine_t *r, uint32_t t, int64_t lt, int64_t lu[4])
{
  int n = 0;
  for (int i = 0; i < 4; i++) {
    lu[i] = neighbour_label(r, t, i);
    n += face_written_here(lt, lu[i]);
  }
  return n;
}

/* Pass 1: per chunk, the kept tets and interface triangles; marks the vertices used. */
static void extract_count(const i2m_refine_t *r, uint8_t *used, int64_t *ntet, int64_t *ntri, i2m_progress_t *pg)
{
  const i2m_dt_t *dt = r->dt;
  uint32_t nslots = i2m_dt_ntets_slots(dt);
  I2M_OMP(omp parallel for schedule(dynamic, 4))
  for (int c = 0; c < EXTRACT_CHUNKS; c++) {
    uint32_t lo = (uint32_t)((uint64_t)nslots * c / EXTRACT_CHUNKS), hi = (uint32_t)((uint64_t)nslots * (c + 1) / EXTRACT_CHUNKS);
    int64_t nt = 0, nf = 0;
    for (uint32_t t = lo; t < hi; t++) {
      if (!tet_kept(r->dt, t)) continue;
      nt++;
      int64_t lu[4];
      nf += faces_to_write(r, t, r->img->label_value[tinfo(dt, t)->label], lu);
      for (int i = 0; i < 4; i++) /* the same value from any thread: an atomic store */
        atomic_store_explicit((_Atomic uint8_t *)&used[dt->tv[4 * (size_t)t + i]], 1, memory_order_relaxed);
    }
    ntet[c + 1] = nt;
    ntri[c + 1] = nf;
    i2m_progress_add(pg, chunk_slots(dt, c));
  }
  ntet[0] = ntri[0] = 0;
  for (int c = 0; c < EXTRACT_CHUNKS; c++) { /* offsets */
    ntet[c + 1] += ntet[c];
    ntri[c + 1] += ntri[c];
  }
}

/* Pass 2: the tets and triangles of chunk c at its offsets. */
static void extract_fill_chunk(const i2m_refine_t *r, const int32_t *vmap, i2m_tetmesh_t *m, int c, int64_t kt,
                               int64_t kf)
{
  const i2m_dt_t *dt = r->dt;
  uint32_t nslots = i2m_dt_ntets_slots(dt);
  uint32_t lo = (uint32_t)((uint64_t)nslots * c / EXTRACT_CHUNKS), hi = (uint32_t)((uint64_t)nslots * (c + 1) / EXTRACT_CHUNKS);
  for (uint32_t t = lo; t < hi; t++) {
    if (!tet_kept(r->dt, t)) continue;
    const uint32_t *v = dt->tv + 4 * (size_t)t;
    int64_t lt = r->img->label_value[tinfo(dt, t)->label], lu[4];
    for (int i = 0; i < 4; i++) m->tet[4 * kt + i] = vmap[v[i]];
    m->tet_label[kt++] = lt;
    faces_to_write(r, t, lt, lu);
    for (int i = 0; i < 4; i++) {
      if (!face_written_here(lt, lu[i])) continue;
      /* FACE_OUT points from lt to lu[i]; the normal must point from the higher label to the
       * lower: kept when lu[i] is the background (out of the domain), flipped when lt ranks
       * below the tissue lu[i] */
      const bool flip = lu[i] != 0;
      int32_t *f = m->tri + 3 * kf;
      for (int k = 0; k < 3; k++) f[k] = vmap[v[FACE_OUT[i][k]]];
      if (flip) {
        int32_t x = f[0];
        f[0] = f[1];
        f[1] = x;
      }
      m->tri_label[2 * kf] = flip ? lt : lu[i]; /* (the lower first) */
      m->tri_label[2 * kf + 1] = flip ? lu[i] : lt;
      kf++;
    }
  }
}

i2m_err_t i2m_refine_extract(const i2m_refine_t *r, i2m_tetmesh_t **out)
{
  const i2m_dt_t *dt = r->dt;
  int32_t *vmap = NULL;
  uint8_t *used = NULL;
  int64_t *ntet = NULL, *ntri = NULL;
  i2m_tetmesh_t *m = NULL;
  i2m_err_t err = I2M_OK;
  uint32_t nvs = i2m_dt_nverts_slots(dt);
  *out = NULL;
  I2M_CALL_GOTO(err, done, i2m_calloc(nvs, sizeof *used, &used));
  I2M_CALL_GOTO(err, done, i2m_malloc(nvs, sizeof *vmap, &vmap));
  I2M_CALL_GOTO(err, done, i2m_malloc(EXTRACT_CHUNKS + 1, sizeof *ntet, &ntet));
  I2M_CALL_GOTO(err, done, i2m_malloc(EXTRACT_CHUNKS + 1, sizeof *ntri, &ntri));
  i2m_progress_t pg; /* (two passes over the slots) */
  i2m_progress_begin_total(&pg, "extraction", "tet slots", 2 * (int64_t)i2m_dt_ntets_slots(dt));
  extract_count(r, used, ntet, ntri, &pg);
  int64_t nv = 0;
  for (uint32_t v = 0; v < nvs; v++) vmap[v] = used[v] ? (int32_t)nv++ : -1;
  I2M_CALL_GOTO(err, done, i2m_tetmesh_create(nv, ntet[EXTRACT_CHUNKS], ntri[EXTRACT_CHUNKS], &m));
  if (dist_tracking(r)) I2M_CALL_GOTO(err, done, i2m_malloc((size_t)(nv ? nv : 1), sizeof *m->gid, &m->gid));
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t v = 0; v < (int64_t)nvs; v++) {
    if (vmap[v] < 0) continue;
    const double *x = i2m_dt_xyz(dt, (uint32_t)v);
    double *w = m->xyz + 3 * (size_t)vmap[v];
    for (int a = 0; a < 3; a++) w[a] = dt->shifted ? x[a] + dt->shift[a] : x[a]; /* (exact: the points were snapped) */
    if (m->gid) m->gid[vmap[v]] = i2m_dt_gid(dt, (uint32_t)v);
  }
  I2M_OMP(omp parallel for schedule(dynamic, 4))
  for (int c = 0; c < EXTRACT_CHUNKS; c++) {
    extract_fill_chunk(r, vmap, m, c, ntet[c], ntri[c]);
    i2m_progress_add(&pg, chunk_slots(dt, c));
  }
  i2m_progress_end(&pg, 2 * (int64_t)i2m_dt_ntets_slots(dt));
  *out = m;
  m = NULL;
done:
  i2m_free(&vmap);
  i2m_free(&used);
  i2m_free(&ntet);
  i2m_free(&ntri);
  i2m_tetmesh_destroy(&m);
  return err;
}
