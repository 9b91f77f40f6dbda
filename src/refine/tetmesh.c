/* Refine layer: the labelled output mesh container: allocation, and its order (tets along a
 * space-filling curve, vertices numbered as they first come: a file that compresses by a
 * third more, and for a solver a matrix whose rows touch nearby memory). */
#include <string.h>

#include "i2m/tetmesh.h"

i2m_err_t i2m_tetmesh_create(int64_t nv, int64_t nt, int64_t ntri, i2m_tetmesh_t **out)
{
  i2m_err_t err = I2M_OK;
  i2m_tetmesh_t *m = NULL;
  *out = NULL;
  I2M_CHECK(nv >= 0 && nt >= 0 && ntri >= 0, I2M_ERR_INTERNAL, "negative mesh size");
  I2M_CALL(i2m_calloc(1, sizeof *m, &m));
  m->nv = nv;
  m->nt = nt;
  m->ntri = ntri;
  I2M_CALL_GOTO(err, fail, i2m_realloc_large((size_t)nv * 3, sizeof(double), &m->xyz));
  I2M_CALL_GOTO(err, fail, i2m_realloc_large((size_t)nt * 4, sizeof(int32_t), &m->tet));
  I2M_CALL_GOTO(err, fail, i2m_realloc_large((size_t)nt, sizeof(int64_t), &m->tet_label));
  I2M_CALL_GOTO(err, fail, i2m_realloc_large((size_t)ntri * 3, sizeof(int32_t), &m->tri));
  I2M_CALL_GOTO(err, fail, i2m_realloc_large((size_t)ntri * 2, sizeof(int64_t), &m->tri_label));
  *out = m;
  return I2M_OK;
fail:
  i2m_tetmesh_destroy(&m);
  return err;
}

void i2m_tetmesh_destroy(i2m_tetmesh_t **m)
{
  if (!m || !*m) return;
  i2m_free(&(*m)->xyz);
  i2m_free(&(*m)->tet);
  i2m_free(&(*m)->tet_label);
  i2m_free(&(*m)->tri);
  i2m_free(&(*m)->tri_label);
  i2m_free(&(*m)->gid);
  i2m_free(m);
}

/* ---- the output order ---- */

#define ORDER_BITS 8 /* cells along each axis of the mesh's box: 2^8, a few tets each */

/* code << 32 | index of each element (the code of its first vertex) into words[0..n). */
static void element_codes(const uint32_t *vcode, const int32_t *vert, int per, int64_t n, uint64_t *words)
{
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t e = 0; e < n; e++) words[e] = (uint64_t)vcode[vert[per * e]] << 32 | (uint64_t)e;
}

/* The elements (per vertices each, and a label row of lab_per) in the order of sorted[], their
 * vertices renumbered by new_of, into fresh arrays that take the old ones' place. */
static i2m_err_t permute_elements(int32_t **vert, int64_t **lab, int per, int lab_per, int64_t n,
                                  const uint64_t *sorted, const int32_t *new_of)
{
  int32_t *v2 = NULL;
  int64_t *l2 = NULL;
  I2M_CALL(i2m_realloc_large((size_t)n * (size_t)per, sizeof *v2, &v2));
  i2m_err_t err = i2m_realloc_large((size_t)n * (size_t)lab_per, sizeof *l2, &l2);
  if (err != I2M_OK) {
    i2m_free(&v2);
    return err;
  }
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t k = 0; k < n; k++) {
    const size_t e = (uint32_t)sorted[k];
    for (int j = 0; j < per; j++) v2[per * k + j] = new_of[(*vert)[(size_t)per * e + (size_t)j]];
    for (int j = 0; j < lab_per; j++) l2[lab_per * k + j] = (*lab)[(size_t)lab_per * e + (size_t)j];
  }
  i2m_free(vert);
  i2m_free(lab);
  *vert = v2;
  *lab = l2;
  return I2M_OK;
}

/* The grid of the curve: lo and the scale that maps the mesh's box onto 2^ORDER_BITS cells. */
static void curve_grid(const i2m_tetmesh_t *m, double lo[3], double scale[3])
{
  double hi[3];
  for (int a = 0; a < 3; a++) lo[a] = hi[a] = m->xyz[a];
  for (int64_t v = 1; v < m->nv; v++)
    for (int a = 0; a < 3; a++) {
      const double x = m->xyz[3 * v + a];
      lo[a] = x < lo[a] ? x : lo[a];
      hi[a] = x > hi[a] ? x : hi[a];
    }
  for (int a = 0; a < 3; a++) scale[a] = hi[a] > lo[a] ? (double)(1u << ORDER_BITS) / (hi[a] - lo[a]) : 0.0;
}

/* new_of[v]: vertex v's number in the order the tets of sorted[] first use it (a vertex of no
 * tet, which extraction does not make, comes last). */
static void number_by_first_use(const i2m_tetmesh_t *m, const uint64_t *sorted, int32_t *new_of)
{
  for (int64_t v = 0; v < m->nv; v++) new_of[v] = -1;
  int32_t next = 0;
  for (int64_t k = 0; k < m->nt; k++) {
    const int32_t *tv = m->tet + 4 * (size_t)(uint32_t)sorted[k];
    for (int j = 0; j < 4; j++)
      if (new_of[tv[j]] < 0) new_of[tv[j]] = next++;
  }
  for (int64_t v = 0; v < m->nv; v++)
    if (new_of[v] < 0) new_of[v] = next++;
}

/* Each vertex's coordinates (and global id) moved to its new number. */
static i2m_err_t move_vertices(i2m_tetmesh_t *m, const int32_t *new_of)
{
  double *xyz = NULL;
  int64_t *gid = NULL;
  I2M_CALL(i2m_realloc_large((size_t)m->nv * 3, sizeof *xyz, &xyz));
  const i2m_err_t err = m->gid ? i2m_malloc((size_t)m->nv, sizeof *gid, &gid) : I2M_OK;
  if (err != I2M_OK) {
    i2m_free(&xyz);
    return err;
  }
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t v = 0; v < m->nv; v++) {
    memcpy(xyz + 3 * (size_t)new_of[v], m->xyz + 3 * (size_t)v, 3 * sizeof *xyz);
    if (gid) gid[new_of[v]] = m->gid[v];
  }
  i2m_free(&m->xyz);
  m->xyz = xyz;
  if (gid) {
    i2m_free(&m->gid);
    m->gid = gid;
  }
  return I2M_OK;
}

i2m_err_t i2m_tetmesh_sort(i2m_tetmesh_t *m)
{
  if (m->nt == 0 || m->nv == 0) return I2M_OK;
  if (m->nt > UINT32_MAX || m->ntri > UINT32_MAX) return I2M_OK; /* (a sort word holds a 32-bit index: left as it is) */
  double lo[3], scale[3];
  curve_grid(m, lo, scale);
  const int64_t nw = m->nt > m->ntri ? m->nt : m->ntri;
  uint64_t *words = NULL, *scratch = NULL;
  int32_t *new_of = NULL;
  uint32_t *vcode = NULL; /* (each vertex's code: the elements' codes read a small array) */
  i2m_err_t err = I2M_OK;
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)nw, sizeof *words, &words));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)nw, sizeof *scratch, &scratch));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)m->nv, sizeof *new_of, &new_of));
  I2M_CALL_GOTO(err, done, i2m_malloc((size_t)m->nv, sizeof *vcode, &vcode));
  I2M_OMP(omp parallel for schedule(static))
  for (int64_t v = 0; v < m->nv; v++) vcode[v] = i2m_morton_code(m->xyz + 3 * v, lo, scale, ORDER_BITS);
  /* the tets along the curve, their vertices numbered as they first come */
  element_codes(vcode, m->tet, 4, m->nt, words);
  const uint64_t *sorted = i2m_sort_by_code(words, scratch, (size_t)m->nt, 3 * ORDER_BITS);
  number_by_first_use(m, sorted, new_of);
  I2M_CALL_GOTO(err, done, permute_elements(&m->tet, &m->tet_label, 4, 1, m->nt, sorted, new_of));
  I2M_CALL_GOTO(err, done, move_vertices(m, new_of));
  /* the triangles along the curve too (vcode is in the old numbers, as the triangles still are) */
  if (m->ntri) {
    element_codes(vcode, m->tri, 3, m->ntri, words);
    sorted = i2m_sort_by_code(words, scratch, (size_t)m->ntri, 3 * ORDER_BITS);
    I2M_CALL_GOTO(err, done, permute_elements(&m->tri, &m->tri_label, 3, 2, m->ntri, sorted, new_of));
  }
done:
  i2m_free(&words);
  i2m_free(&scratch);
  i2m_free(&new_of);
  i2m_free(&vcode);
  return err;
}
