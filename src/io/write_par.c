/* io layer: a distributed mesh written as pieces (.pvtu: every rank writes its own .vtu and
 * its interfaces .vtu, rank 0 the two files that name them, no gather) or stitched on rank 0
 * into one file. */
#include "io_impl.h"

#include <string.h>

/* NAME.pvtu -> NAME_<rank>.vtu (path) and its name without the directory (source); the
 * same for the interfaces file NAME.interfaces.pvtu -> NAME_<rank>.interfaces.vtu, the
 * companion the VTU writer gives piece NAME_<rank>.vtu. */
static i2m_err_t piece_names(const char *pvtu, int rank, bool interfaces, char *path, size_t np, char *source, size_t ns)
{
  static const char suffix[] = ".interfaces.pvtu";
  const size_t n = strlen(pvtu), cut = interfaces ? sizeof suffix - 1 : 5;
  I2M_CHECK(n > cut && n + 40 < np, I2M_ERR_ARG, "%s: bad piece file name", pvtu);
  snprintf(path, np, "%.*s_%d%s.vtu", (int)(n - cut), pvtu, rank, interfaces ? ".interfaces" : "");
  const char *slash = strrchr(path, '/');
  snprintf(source, ns, "%s", slash ? slash + 1 : path);
  return I2M_OK;
}

/* The .pvtu naming the pieces: of the mesh (cell data material) or of its interface
 * triangles (cell data label_a, label_b); gids: the pieces have the point data GlobalNodeId
 * (the pieces of a distributed run; not those of one process). */
static i2m_err_t write_pvtu(const char *path, int pieces, int wide, bool gids, bool interfaces)
{
  const char *type = wide ? "Int64" : "Int32";
  io_out_t o;
  I2M_CALL(io_out_open(&o, path));
  io_out_printf(&o,
                "<?xml version=\"1.0\"?>\n"
                "<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
                "  <PUnstructuredGrid GhostLevel=\"0\">\n");
  if (gids)
    io_out_printf(&o,
                  "    <PPointData GlobalIds=\"GlobalNodeId\">\n"
                  "      <PDataArray type=\"Int64\" Name=\"GlobalNodeId\"/>\n"
                  "    </PPointData>\n");
  if (interfaces)
    io_out_printf(&o,
                  "    <PCellData>\n"
                  "      <PDataArray type=\"%s\" Name=\"label_a\"/>\n"
                  "      <PDataArray type=\"%s\" Name=\"label_b\"/>\n"
                  "    </PCellData>\n", type, type);
  else
    io_out_printf(&o,
                  "    <PCellData Scalars=\"material\">\n"
                  "      <PDataArray type=\"%s\" Name=\"material\"/>\n"
                  "    </PCellData>\n", type);
  io_out_printf(&o,
                "    <PPoints>\n"
                "      <PDataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\"/>\n"
                "    </PPoints>\n");
  for (int q = 0; q < pieces && o.err == I2M_OK; q++) {
    char p[4096], src[4096];
    o.err = piece_names(path, q, interfaces, p, sizeof p, src, sizeof src);
    io_out_printf(&o, "    <Piece Source=\"%s\"/>\n", src);
  }
  io_out_printf(&o, "  </PUnstructuredGrid>\n</VTKFile>\n");
  return io_out_close(&o);
}

/* Rank 0: NAME.pvtu and NAME.interfaces.pvtu. */
static i2m_err_t write_pvtus(const char *path, int pieces, int wide, bool gids)
{
  char companion[4096];
  I2M_CHECK(i2m_mesh_interfaces_path(path, companion, sizeof companion), I2M_ERR_ARG,
            "%s: path too long for its interfaces file", path);
  I2M_CALL(write_pvtu(path, pieces, wide, gids, false));
  return write_pvtu(companion, pieces, wide, gids, true);
}

/* Does a label need 64 bits (on any rank: the pieces must agree on the type)? */
static int wide_labels(const i2m_par_t *par, const i2m_tetmesh_t *m)
{
  int wide = 0;
  for (int64_t t = 0; t < m->nt; t++)
    if (m->tet_label[t] < INT32_MIN || m->tet_label[t] > INT32_MAX) wide = 1;
  return i2m_par_max(par, wide) > 0;
}

i2m_err_t i2m_mesh_write_par(const i2m_par_t *par, i2m_tetmesh_t **m, const char *path, const i2m_write_opts_t *opts)
{
  const i2m_write_opts_t o = opts ? *opts : i2m_write_opts_default();
  if (i2m_format_from_path(path) == I2M_FORMAT_PVTU) {
    char piece[4096], source[4096];
    i2m_err_t err = piece_names(path, par->rank, false, piece, sizeof piece, source, sizeof source);
    const int wide = wide_labels(par, *m);
    const bool gids = i2m_par_max(par, (*m)->gid != NULL) > 0; /* (the same on every rank) */
    if (err == I2M_OK) err = io_write_vtu_typed(*m, piece, wide, &o);
    err = i2m_par_agree(par, err);
    if (err == I2M_OK && par->rank == 0) err = write_pvtus(path, par->size, wide, gids);
    return i2m_par_agree(par, err);
  }
  if (par->size > 1) {
    I2M_CALL(i2m_par_agree(par, i2m_dist_gather_mesh(par, m)));
  }
  i2m_err_t err = I2M_OK;
  if (par->rank == 0) {
    i2m_free(&(*m)->gid); /* (one file: the ids were for stitching) */
    err = i2m_mesh_write(*m, path, &o);
  }
  return i2m_par_agree(par, err);
}
