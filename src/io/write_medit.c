/* io layer: Medit ASCII writer (.mesh).  Vertices (ref 0), tetrahedra (ref = label value),
 * interface triangles (ref = number of the label pair, 1..P in (a,b) order).  A comment
 * block before "Triangles" maps each number to its pair:
 *   # i2m interface 3 = labels 13 20
 * Vertex ids are 1-based; coordinates are printed with %.17g (exact round trip). */
#include "io_impl.h"

#include <stdio.h>

#define MEDIT_LINE 512

static void medit_vertices(io_out_t *o, const i2m_tetmesh_t *m)
{
  io_out_printf(o, "Vertices\n%lld\n", (long long)m->nv);
  for (int64_t v = 0; v < m->nv; v++) {
    char *p = io_out_reserve(o, MEDIT_LINE);
    if (!p) return;
    const double *x = m->xyz + 3 * v;
    int k = snprintf(p, MEDIT_LINE, "%.17g %.17g %.17g 0\n", x[0], x[1], x[2]);
    io_out_commit(o, (size_t)k);
  }
}

/* One element line: n 1-based ids then the ref. */
static void medit_element(io_out_t *o, const int32_t *ids, int n, int64_t ref)
{
  char *p = io_out_reserve(o, MEDIT_LINE);
  if (!p) return;
  int k = 0;
  for (int i = 0; i < n; i++) {
    k += io_fmt_i64(p + k, (int64_t)ids[i] + 1);
    p[k++] = ' ';
  }
  k += io_fmt_i64(p + k, ref);
  p[k++] = '\n';
  io_out_commit(o, (size_t)k);
}

i2m_err_t io_write_medit(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts)
{
  (void)opts;
  int64_t *pairs = NULL, npairs = 0;
  int32_t *tri_pair = NULL;
  io_out_t o;
  I2M_CALL(io_interface_pairs(m, &pairs, &npairs, &tri_pair));
  i2m_err_t err = io_out_open(&o, path);
  if (err != I2M_OK) goto done;
  io_out_printf(&o, "MeshVersionFormatted 2\n\nDimension 3\n\n");
  medit_vertices(&o, m);
  io_out_printf(&o, "\nTetrahedra\n%lld\n", (long long)m->nt);
  for (int64_t t = 0; t < m->nt; t++) medit_element(&o, m->tet + 4 * t, 4, m->tet_label[t]);
  if (m->ntri > 0) {
    io_out_printf(&o, "\n# i2m interfaces: a triangle's ref numbers the label pair (a,b)\n"
                      "# of the tissues on its two sides (0: outside); its normal points from\n"
                      "# b to a, from the higher label to the lower (out of the domain for 0).\n");
    for (int64_t p = 0; p < npairs; p++)
      io_out_printf(&o, "# i2m interface %lld = labels %lld %lld\n", (long long)(p + 1),
                    (long long)pairs[2 * p], (long long)pairs[2 * p + 1]);
    io_out_printf(&o, "Triangles\n%lld\n", (long long)m->ntri);
    for (int64_t i = 0; i < m->ntri; i++)
      medit_element(&o, m->tri + 3 * i, 3, (int64_t)tri_pair[i] + 1);
  }
  io_out_printf(&o, "\nEnd\n");
  err = io_out_close(&o);
done:
  i2m_free(&pairs);
  i2m_free(&tri_pair);
  return err;
}
