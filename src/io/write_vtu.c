/* io layer: VTK XML unstructured grid writer (.vtu).  Appended raw binary data with UInt64
 * block headers, little-endian whatever the host: Points Float64, connectivity and offsets
 * Int64, types UInt8 (VTK_TETRA = 10), cell data "material" (Int32 when every label fits,
 * else Int64).  Arrays are converted chunk by chunk straight into the output buffer. */
#include "io_impl.h"

#include <string.h>

#define VTU_CHUNK 65536 /* values converted per reserve() */

/* Writes one appended block: the UInt64 byte count, then the values produced by kind. */
enum { VTU_POINTS, VTU_CONN, VTU_OFFSETS, VTU_TYPES, VTU_MAT32, VTU_MAT64, VTU_GID };

static size_t vtu_value_bytes(int kind)
{
  switch (kind) {
  case VTU_TYPES: return 1;
  case VTU_MAT32: return 4;
  default: return 8;
  }
}

static int64_t vtu_count(const i2m_tetmesh_t *m, int kind)
{
  if (kind == VTU_POINTS) return 3 * m->nv;
  if (kind == VTU_GID) return m->nv;
  if (kind == VTU_CONN) return 4 * m->nt;
  return m->nt;
}

static void vtu_block(io_out_t *o, const i2m_tetmesh_t *m, int kind)
{
  size_t vb = vtu_value_bytes(kind);
  int64_t n = vtu_count(m, kind);
  char hdr[8];
  io_le64(hdr, (uint64_t)n * vb);
  io_out_put(o, hdr, 8);
  for (int64_t s = 0; s < n; s += VTU_CHUNK) {
    int64_t e = s + VTU_CHUNK < n ? s + VTU_CHUNK : n;
    char *p = io_out_reserve(o, (size_t)(e - s) * vb);
    if (!p) return;
    for (int64_t i = s; i < e; i++, p += vb) {
      switch (kind) {
      case VTU_POINTS: {
        uint64_t bits;
        memcpy(&bits, &m->xyz[i], 8);
        io_le64(p, bits);
        break;
      }
      case VTU_CONN: io_le64(p, (uint64_t)(int64_t)m->tet[i]); break;
      case VTU_OFFSETS: io_le64(p, (uint64_t)(4 * (i + 1))); break;
      case VTU_TYPES: *p = 10; break;
      case VTU_MAT32: io_le32(p, (uint32_t)(int32_t)m->tet_label[i]); break;
      case VTU_GID: io_le64(p, (uint64_t)m->gid[i]); break;
      default: io_le64(p, (uint64_t)m->tet_label[i]); break;
      }
    }
    io_out_commit(o, (size_t)(e - s) * vb);
  }
}

i2m_err_t io_write_vtu(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts)
{
  int wide = 0;
  for (int64_t t = 0; t < m->nt; t++)
    if (m->tet_label[t] < INT32_MIN || m->tet_label[t] > INT32_MAX) wide = 1;
  return io_write_vtu_typed(m, path, wide, opts);
}

i2m_err_t io_write_vtu_typed(const i2m_tetmesh_t *m, const char *path, int wide, const i2m_write_opts_t *opts)
{
  (void)opts; /* (compression: to come) */
  int kinds[6] = {VTU_POINTS, VTU_CONN, VTU_OFFSETS, VTU_TYPES, wide ? VTU_MAT64 : VTU_MAT32, VTU_GID};
  const int nk = m->gid ? 6 : 5; /* (a piece of a distributed mesh: its vertices' global ids) */
  uint64_t off[6], acc = 0;
  for (int k = 0; k < nk; k++) {
    off[k] = acc;
    acc += 8 + (uint64_t)vtu_count(m, kinds[k]) * vtu_value_bytes(kinds[k]);
  }
  io_out_t o;
  I2M_CALL(io_out_open(&o, path));
  io_out_printf(&o,
                "<?xml version=\"1.0\"?>\n"
                "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\""
                " header_type=\"UInt64\">\n"
                "  <UnstructuredGrid>\n"
                "    <Piece NumberOfPoints=\"%lld\" NumberOfCells=\"%lld\">\n"
                "      <Points>\n"
                "        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\""
                " format=\"appended\" offset=\"%llu\"/>\n"
                "      </Points>\n",
                (long long)m->nv, (long long)m->nt, (unsigned long long)off[0]);
  if (m->gid)
    io_out_printf(&o,
                  "      <PointData GlobalIds=\"GlobalNodeId\">\n"
                  "        <DataArray type=\"Int64\" Name=\"GlobalNodeId\" format=\"appended\" offset=\"%llu\"/>\n"
                  "      </PointData>\n",
                  (unsigned long long)off[5]);
  io_out_printf(&o, "      <Cells>\n");
  io_out_printf(&o,
                "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"appended\""
                " offset=\"%llu\"/>\n"
                "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"appended\""
                " offset=\"%llu\"/>\n"
                "        <DataArray type=\"UInt8\" Name=\"types\" format=\"appended\""
                " offset=\"%llu\"/>\n"
                "      </Cells>\n"
                "      <CellData Scalars=\"material\">\n"
                "        <DataArray type=\"%s\" Name=\"material\" format=\"appended\""
                " offset=\"%llu\"/>\n"
                "      </CellData>\n"
                "    </Piece>\n"
                "  </UnstructuredGrid>\n"
                "  <AppendedData encoding=\"raw\">\n   _",
                (unsigned long long)off[1], (unsigned long long)off[2],
                (unsigned long long)off[3], wide ? "Int64" : "Int32",
                (unsigned long long)off[4]);
  for (int k = 0; k < nk; k++) vtu_block(&o, m, kinds[k]);
  io_out_printf(&o, "\n  </AppendedData>\n</VTKFile>\n");
  return io_out_close(&o);
}
