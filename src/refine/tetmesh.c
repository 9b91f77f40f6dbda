/* Refine layer: allocation of the labelled output mesh container. */
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
