/* Refine layer: extraction of the labelled mesh (REFERENCE §1.8): the tets whose
 * circumcentre is inside, labelled there; the interface triangles between different labels
 * (normal from the smaller label value to the larger); compacted vertices.  The mesher works
 * in world coordinates, so the tets keep the exact positive orientation the kernel gave. */
#include "refine_impl.h"

#include <string.h>

/* Face i of a positive tet with its outward normal (right-hand rule). */
static const int FACE_OUT[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

static int64_t neighbour_label(const i2m_refine_t *r, uint32_t t, int i)
{
  uint32_t n = r->dt->tn[4 * t + i];
  return n == I2M_DT_NONE ? 0 : r->img->label_value[tinfo(r->dt, n >> 2)->label];
}

/* Counts kept tets and interface triangles, and numbers the vertices they use. */
static void extract_count(const i2m_refine_t *r, int32_t *vmap, int64_t *nv, int64_t *nt, int64_t *ntri)
{
  const i2m_dt_t *dt = r->dt;
  uint32_t nslots = i2m_dt_ntets_slots(dt);
  *nv = *nt = *ntri = 0;
  for (uint32_t t = 0; t < nslots; t++) {
    if (!i2m_dt_alive(dt, t) || tinfo(dt, t)->label == 0) continue;
    (*nt)++;
    int64_t lt = r->img->label_value[tinfo(dt, t)->label];
    for (int i = 0; i < 4; i++) {
      uint32_t v = dt->tv[4 * (size_t)t + i];
      if (vmap[v] < 0) vmap[v] = (int32_t)(*nv)++;
      int64_t lu = neighbour_label(r, t, i);
      if (lu != lt && (lu == 0 || lt < lu)) (*ntri)++;
    }
  }
}

i2m_err_t i2m_refine_extract(const i2m_refine_t *r, i2m_tetmesh_t **out)
{
  const i2m_dt_t *dt = r->dt;
  const i2m_image_t *img = r->img;
  int32_t *vmap = NULL;
  i2m_tetmesh_t *m = NULL;
  i2m_err_t err = I2M_OK;
  uint32_t nvs = i2m_dt_nverts_slots(dt), nslots = i2m_dt_ntets_slots(dt);
  *out = NULL;
  I2M_CALL(i2m_malloc(nvs, sizeof *vmap, &vmap));
  for (uint32_t v = 0; v < nvs; v++) vmap[v] = -1;
  int64_t nv, nt, ntri;
  extract_count(r, vmap, &nv, &nt, &ntri);
  I2M_CALL_GOTO(err, done, i2m_tetmesh_create(nv, nt, ntri, &m));
  for (uint32_t v = 0; v < nvs; v++)
    if (vmap[v] >= 0) memcpy(m->xyz + 3 * (size_t)vmap[v], i2m_dt_xyz(dt, v), 3 * sizeof(double));
  int64_t kt = 0, kf = 0;
  for (uint32_t t = 0; t < nslots; t++) {
    if (!i2m_dt_alive(dt, t) || tinfo(dt, t)->label == 0) continue;
    const uint32_t *v = dt->tv + 4 * (size_t)t;
    int64_t lt = img->label_value[tinfo(dt, t)->label];
    int32_t *q = m->tet + 4 * kt;
    for (int i = 0; i < 4; i++) q[i] = vmap[v[i]];
    m->tet_label[kt++] = lt;
    for (int i = 0; i < 4; i++) {
      int64_t lu = neighbour_label(r, t, i);
      if (lu == lt || !(lu == 0 || lt < lu)) continue;
      /* the outward normal goes from lt to lu: keep it when lt is the smaller value */
      bool keep = lt < lu;
      int32_t *f = m->tri + 3 * kf;
      for (int k = 0; k < 3; k++) f[k] = vmap[v[FACE_OUT[i][k]]];
      if (!keep) {
        int32_t x = f[0];
        f[0] = f[1];
        f[1] = x;
      }
      m->tri_label[2 * kf] = lt < lu ? lt : lu;
      m->tri_label[2 * kf + 1] = lt < lu ? lu : lt;
      kf++;
    }
  }
  *out = m;
  m = NULL;
done:
  i2m_free(&vmap);
  i2m_tetmesh_destroy(&m);
  return err;
}
