/* io layer: VTK XML unstructured grid writer (.vtu), little-endian whatever the host, UInt64
 * headers.  Two files per mesh:
 *   NAME.vtu             Points Float64, connectivity Int32 (the vertex ids are 32-bit:
 *                        half the bytes of Int64 to convert, compress and write), offsets
 *                        Int32 (Int64 past 2^31 - 1), types UInt8
 *                        (VTK_TETRA = 10), cell data "material" (Int32 when every label fits,
 *                        else Int64); a piece of a distributed mesh adds the point data
 *                        GlobalNodeId (Int64);
 *   NAME.interfaces.vtu  the interface triangles (VTK_TRIANGLE = 5) on the vertices they use,
 *                        cell data "label_a" and "label_b" (the lower label first: 0, the
 *                        outside, then tissues by value; the material type), each triangle's
 *                        normal (right-hand rule) pointing from label_b to label_a, out of
 *                        the meshed domain on its boundary; GlobalNodeId for a piece.
 * Appended data, zlib-compressed by default (compressor="vtkZLibDataCompressor": each array is
 * a header [blocks, block size, size of the last partial block or 0, compressed size of each
 * block] then the blocks, each compressed on its own); raw with opts->compress false (each
 * array a byte count then the values).  Compressed blocks are made in parallel (independent
 * 1 MiB blocks at zlib level 1, the quickest level that compresses: the knee's mesh at the
 * default delta comes out 3.1 times smaller than raw, its tets in curve order, i2m_tetmesh_sort)
 * and held in memory until the XML header, which gives every array's offset,
 * is written; raw arrays are converted chunk by chunk straight into the output buffer. */
#include "io_impl.h"

#include <stdatomic.h>
#include <string.h>
#include <zlib.h>

#define VTU_CHUNK 65536                 /* values converted per reserve() (raw) */
#define VTU_BLOCK ((size_t)1 << 20)     /* bytes per compressed block, before compression */
#define VTU_ZLEVEL 1                    /* the quickest level (the default, 6, is slower) */

enum { VTK_TRIANGLE = 5, VTK_TETRA = 10 };

/* Where an array's values come from. */
typedef enum {
  SRC_F64,     /* doubles */
  SRC_I32,     /* int32 ids */
  SRC_I64,     /* int64 values */
  SRC_OFFSETS, /* step * (i + 1) */
  SRC_CONST    /* step */
} vtu_src_t;

enum { SEC_POINTS, SEC_POINTDATA, SEC_CELLS, SEC_CELLDATA, SEC_COUNT };

/* One DataArray.  Value i is data[(map ? map[i / per] * per + i % per : i) * stride + first]
 * (or computed, for SRC_OFFSETS and SRC_CONST), written in `width` bytes. */
typedef struct {
  const char *name, *type; /* XML Name and type */
  int section, ncomp;
  int64_t count;           /* values (ncomp per tuple) */
  int width;               /* bytes per value in the file: 1, 4 or 8 */
  vtu_src_t src;
  const void *data;        /* borrowed */
  const int32_t *map;      /* borrowed, or NULL */
  int per, stride, first;
  int64_t step;
  /* compressed form (owned) */
  int64_t nblocks;
  unsigned char **zblock;  /* [nblocks] */
  uint64_t *zsize;         /* [nblocks] */
} vtu_array_t;

#define VTU_MAX_ARRAYS 8

/* A grid to write: its counts and arrays, in the order of the appended data. */
typedef struct {
  int64_t npoints, ncells;
  vtu_array_t a[VTU_MAX_ARRAYS];
  int n;
  const char *scalars; /* borrowed, or NULL: the cell data shown by default */
} vtu_grid_t;

static vtu_array_t *grid_add(vtu_grid_t *g, const char *name, const char *type, int section, int64_t count)
{
  vtu_array_t *a = &g->a[g->n++];
  memset(a, 0, sizeof *a);
  a->name = name;
  a->type = type;
  a->section = section;
  a->ncomp = 1;
  a->count = count;
  a->width = strcmp(type, "UInt8") == 0 ? 1 : strcmp(type, "Int32") == 0 ? 4 : 8;
  a->per = a->stride = 1;
  return a;
}

static int64_t src_index(const vtu_array_t *a, int64_t i)
{
  const int64_t e = a->map ? (int64_t)a->map[i / a->per] * a->per + i % a->per : i;
  return e * a->stride + a->first;
}

/* An integer in w bytes (4 or 8), little-endian at p. */
static inline void put_int(char *p, size_t w, int64_t v)
{
  if (w == 4) io_le32(p, (uint32_t)(int32_t)v);
  else io_le64(p, (uint64_t)v);
}

/* Values [s, e) of a, little-endian at p. */
static void vtu_fill(const vtu_array_t *a, int64_t s, int64_t e, char *p)
{
  const size_t w = (size_t)a->width;
  switch (a->src) {
  case SRC_F64:
    for (int64_t i = s; i < e; i++, p += w) {
      uint64_t bits;
      memcpy(&bits, (const double *)a->data + src_index(a, i), 8);
      io_le64(p, bits);
    }
    break;
  case SRC_I32:
    for (int64_t i = s; i < e; i++, p += w) put_int(p, w, ((const int32_t *)a->data)[src_index(a, i)]);
    break;
  case SRC_I64:
    for (int64_t i = s; i < e; i++, p += w) put_int(p, w, ((const int64_t *)a->data)[src_index(a, i)]);
    break;
  case SRC_OFFSETS:
    for (int64_t i = s; i < e; i++, p += w) put_int(p, w, a->step * (i + 1));
    break;
  case SRC_CONST: memset(p, (int)a->step, (size_t)(e - s) * w); break;
  }
}

static uint64_t raw_bytes(const vtu_array_t *a) { return (uint64_t)a->count * (uint64_t)a->width; }

/* Bytes of a in the appended data, header included. */
static uint64_t stored_bytes(const vtu_array_t *a, bool compress)
{
  if (!compress) return 8 + raw_bytes(a);
  uint64_t n = 8 * (3 + (uint64_t)a->nblocks);
  for (int64_t b = 0; b < a->nblocks; b++) n += a->zsize[b];
  return n;
}

/* ---- compression ---- */

static void grid_free_blocks(vtu_grid_t *g)
{
  for (int k = 0; k < g->n; k++) {
    vtu_array_t *a = &g->a[k];
    for (int64_t b = 0; a->zblock && b < a->nblocks; b++) i2m_free(&a->zblock[b]);
    i2m_free(&a->zblock);
    i2m_free(&a->zsize);
    a->nblocks = 0;
  }
}

enum { Z_FAIL_NONE = 0, Z_FAIL_MEMORY, Z_FAIL_ZLIB };

/* Block b of a: converted into raw, compressed into z (compressBound(VTU_BLOCK) bytes), kept
 * in an allocation of its exact size.  Returns a Z_FAIL_* code. */
static int compress_block(vtu_array_t *a, int64_t b, char *raw, unsigned char *z)
{
  const int64_t per_block = (int64_t)(VTU_BLOCK / (size_t)a->width);
  const int64_t s = b * per_block, e = s + per_block < a->count ? s + per_block : a->count;
  vtu_fill(a, s, e, raw);
  uLongf zlen = compressBound((uLong)VTU_BLOCK);
  const int rc = compress2(z, &zlen, (const Bytef *)raw, (uLong)((size_t)(e - s) * (size_t)a->width), VTU_ZLEVEL);
  if (rc == Z_MEM_ERROR) return Z_FAIL_MEMORY;
  if (rc != Z_OK) return Z_FAIL_ZLIB;
  if (i2m_malloc(zlen ? zlen : 1, 1, &a->zblock[b]) != I2M_OK) return Z_FAIL_MEMORY;
  memcpy(a->zblock[b], z, zlen);
  a->zsize[b] = zlen;
  return Z_FAIL_NONE;
}

/* The block lists of every array (allocated, empty). */
static i2m_err_t grid_alloc_blocks(vtu_grid_t *g, int64_t *first)
{
  first[0] = 0;
  for (int k = 0; k < g->n; k++) {
    vtu_array_t *a = &g->a[k];
    a->nblocks = (int64_t)((raw_bytes(a) + VTU_BLOCK - 1) / VTU_BLOCK);
    I2M_CALL(i2m_calloc((size_t)a->nblocks, sizeof *a->zblock, &a->zblock));
    I2M_CALL(i2m_calloc((size_t)a->nblocks, sizeof *a->zsize, &a->zsize));
    first[k + 1] = first[k] + a->nblocks;
  }
  return I2M_OK;
}

/* Compresses every block of every array, in parallel (blocks are independent). */
static i2m_err_t grid_compress(vtu_grid_t *g, const char *path)
{
  int64_t first[VTU_MAX_ARRAYS + 1];
  i2m_err_t err = grid_alloc_blocks(g, first);
  if (err != I2M_OK) {
    grid_free_blocks(g);
    return I2M_ERROR(err, "%s: out of memory compressing the mesh (try --vtu-raw)", path);
  }
  const int64_t njobs = first[g->n];
  atomic_int fail = Z_FAIL_NONE;
  I2M_OMP(omp parallel)
  {
    char *raw = NULL;
    unsigned char *z = NULL; /* (per thread, reused for every block) */
    if (i2m_malloc(VTU_BLOCK, 1, &raw) != I2M_OK || i2m_malloc(compressBound((uLong)VTU_BLOCK), 1, &z) != I2M_OK)
      atomic_store(&fail, Z_FAIL_MEMORY);
    I2M_OMP(omp for schedule(dynamic, 1))
    for (int64_t j = 0; j < njobs; j++) {
      if (atomic_load_explicit(&fail, memory_order_relaxed) != Z_FAIL_NONE) continue;
      int k = 0;
      while (j >= first[k + 1]) k++;
      const int f = compress_block(&g->a[k], j - first[k], raw, z);
      if (f != Z_FAIL_NONE) atomic_store(&fail, f);
    }
    i2m_free(&raw);
    i2m_free(&z);
  }
  const int f = atomic_load(&fail);
  if (f == Z_FAIL_NONE) return I2M_OK;
  grid_free_blocks(g);
  if (f == Z_FAIL_MEMORY) return I2M_ERROR(I2M_ERR_MEMORY, "%s: out of memory compressing the mesh (try --vtu-raw)", path);
  return I2M_ERROR(I2M_ERR_INTERNAL, "%s: zlib failed to compress the mesh", path);
}

/* ---- the file ---- */

static void write_array_raw(io_out_t *o, const vtu_array_t *a)
{
  char hdr[8];
  io_le64(hdr, raw_bytes(a));
  io_out_put(o, hdr, 8);
  for (int64_t s = 0; s < a->count; s += VTU_CHUNK) {
    const int64_t e = s + VTU_CHUNK < a->count ? s + VTU_CHUNK : a->count;
    char *p = io_out_reserve(o, (size_t)(e - s) * (size_t)a->width);
    if (!p) return;
    vtu_fill(a, s, e, p);
    io_out_commit(o, (size_t)(e - s) * (size_t)a->width);
  }
}

static void write_array_compressed(io_out_t *o, const vtu_array_t *a)
{
  const uint64_t raw = raw_bytes(a), last = raw % VTU_BLOCK;
  const uint64_t head[3] = {(uint64_t)a->nblocks, VTU_BLOCK, last};
  char v[8];
  for (int i = 0; i < 3; i++) {
    io_le64(v, head[i]);
    io_out_put(o, v, 8);
  }
  for (int64_t b = 0; b < a->nblocks; b++) {
    io_le64(v, a->zsize[b]);
    io_out_put(o, v, 8);
  }
  for (int64_t b = 0; b < a->nblocks; b++) io_out_put(o, a->zblock[b], a->zsize[b]);
}

static void write_xml(io_out_t *o, const vtu_grid_t *g, bool compress)
{
  static const char *const sec_open[SEC_COUNT] = {"<Points>", "<PointData>", "<Cells>", "<CellData>"};
  static const char *const sec_close[SEC_COUNT] = {"</Points>", "</PointData>", "</Cells>", "</CellData>"};
  io_out_printf(o,
                "<?xml version=\"1.0\"?>\n"
                "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\""
                " header_type=\"UInt64\"%s>\n"
                "  <UnstructuredGrid>\n"
                "    <Piece NumberOfPoints=\"%lld\" NumberOfCells=\"%lld\">\n",
                compress ? " compressor=\"vtkZLibDataCompressor\"" : "", (long long)g->npoints,
                (long long)g->ncells);
  for (int s = 0; s < SEC_COUNT; s++) {
    uint64_t off = 0;
    int opened = 0;
    for (int k = 0; k < g->n; k++) {
      const vtu_array_t *a = &g->a[k];
      if (a->section == s) {
        if (!opened++) {
          if (s == SEC_POINTDATA) io_out_printf(o, "      <PointData GlobalIds=\"GlobalNodeId\">\n");
          else if (s == SEC_CELLDATA && g->scalars) io_out_printf(o, "      <CellData Scalars=\"%s\">\n", g->scalars);
          else io_out_printf(o, "      %s\n", sec_open[s]);
        }
        char comp[40] = "";
        if (a->ncomp > 1) snprintf(comp, sizeof comp, " NumberOfComponents=\"%d\"", a->ncomp);
        io_out_printf(o, "        <DataArray type=\"%s\" Name=\"%s\"%s format=\"appended\" offset=\"%llu\"/>\n",
                      a->type, a->name, comp, (unsigned long long)off);
      }
      off += stored_bytes(a, compress);
    }
    if (opened) io_out_printf(o, "      %s\n", sec_close[s]);
  }
  io_out_printf(o, "    </Piece>\n  </UnstructuredGrid>\n  <AppendedData encoding=\"raw\">\n   _");
}

/* Writes g to path (compressed blocks freed on return). */
static i2m_err_t grid_write(vtu_grid_t *g, const char *path, bool compress)
{
  if (compress) I2M_CALL(grid_compress(g, path));
  io_out_t o;
  i2m_err_t err = io_out_open(&o, path);
  if (err == I2M_OK) {
    write_xml(&o, g, compress);
    for (int k = 0; k < g->n; k++) {
      if (compress) write_array_compressed(&o, &g->a[k]);
      else write_array_raw(&o, &g->a[k]);
    }
    io_out_printf(&o, "\n  </AppendedData>\n</VTKFile>\n");
    err = io_out_close(&o);
  }
  grid_free_blocks(g);
  return err;
}

/* Cells of nper vertex ids each (int32 ids), their offsets and type. */
static void grid_cells(vtu_grid_t *g, const int32_t *ids, int nper, int type)
{
  vtu_array_t *a = grid_add(g, "connectivity", "Int32", SEC_CELLS, nper * g->ncells);
  a->src = SRC_I32;
  a->data = ids;
  a = grid_add(g, "offsets", nper * g->ncells <= INT32_MAX ? "Int32" : "Int64", SEC_CELLS, g->ncells);
  a->src = SRC_OFFSETS;
  a->step = nper;
  a = grid_add(g, "types", "UInt8", SEC_CELLS, g->ncells);
  a->src = SRC_CONST;
  a->step = type;
}

/* The points (map: [npoints] indices into m's vertices, or NULL for all) and their global ids. */
static void grid_points(vtu_grid_t *g, const i2m_tetmesh_t *m, const int32_t *map)
{
  vtu_array_t *a = grid_add(g, "Points", "Float64", SEC_POINTS, 3 * g->npoints);
  a->ncomp = 3;
  a->src = SRC_F64;
  a->data = m->xyz;
  a->map = map;
  a->per = 3;
  if (!m->gid) return; /* (a piece of a distributed mesh: its vertices' global ids) */
  a = grid_add(g, "GlobalNodeId", "Int64", SEC_POINTDATA, g->npoints);
  a->src = SRC_I64;
  a->data = m->gid;
  a->map = map;
}

static void grid_labels(vtu_grid_t *g, const char *name, const int64_t *labels, int stride, int first, int wide)
{
  vtu_array_t *a = grid_add(g, name, wide ? "Int64" : "Int32", SEC_CELLDATA, g->ncells);
  a->src = SRC_I64;
  a->data = labels;
  a->stride = stride;
  a->first = first;
}

static i2m_err_t write_tets(const i2m_tetmesh_t *m, const char *path, int wide, bool compress)
{
  vtu_grid_t g = {.npoints = m->nv, .ncells = m->nt, .scalars = "material"};
  grid_points(&g, m, NULL);
  grid_cells(&g, m->tet, 4, VTK_TETRA);
  grid_labels(&g, "material", m->tet_label, 1, 0, wide);
  return grid_write(&g, path, compress);
}

/* The vertices the triangles use, in m's order: *used [nused] their indices in m, *tri [ntri][3]
 * the triangles renumbered.  Both owned by the caller. */
static i2m_err_t triangle_vertices(const i2m_tetmesh_t *m, int32_t **used, int64_t *nused, int32_t **tri)
{
  int32_t *slot = NULL;
  *used = *tri = NULL;
  *nused = 0;
  I2M_CALL(i2m_malloc((size_t)(m->nv ? m->nv : 1), sizeof *slot, &slot));
  for (int64_t v = 0; v < m->nv; v++) slot[v] = -1;
  for (int64_t i = 0; i < 3 * m->ntri; i++) slot[m->tri[i]] = 0;
  for (int64_t v = 0; v < m->nv; v++)
    if (slot[v] == 0) slot[v] = (int32_t)(*nused)++;
  i2m_err_t err = i2m_malloc((size_t)(*nused ? *nused : 1), sizeof **used, used);
  if (err == I2M_OK) err = i2m_malloc((size_t)(m->ntri ? 3 * m->ntri : 1), sizeof **tri, tri);
  if (err == I2M_OK) {
    for (int64_t v = 0; v < m->nv; v++)
      if (slot[v] >= 0) (*used)[slot[v]] = (int32_t)v;
    for (int64_t i = 0; i < 3 * m->ntri; i++) (*tri)[i] = slot[m->tri[i]];
  } else {
    i2m_free(used);
    i2m_free(tri);
  }
  i2m_free(&slot);
  return err;
}

static i2m_err_t write_interfaces(const i2m_tetmesh_t *m, const char *path, int wide, bool compress)
{
  int32_t *used = NULL, *tri = NULL;
  int64_t nused = 0;
  I2M_CALL(triangle_vertices(m, &used, &nused, &tri));
  vtu_grid_t g = {.npoints = nused, .ncells = m->ntri, .scalars = NULL};
  grid_points(&g, m, used);
  grid_cells(&g, tri, 3, VTK_TRIANGLE);
  grid_labels(&g, "label_a", m->tri_label, 2, 0, wide);
  grid_labels(&g, "label_b", m->tri_label, 2, 1, wide);
  const i2m_err_t err = grid_write(&g, path, compress);
  i2m_free(&used);
  i2m_free(&tri);
  return err;
}

bool i2m_mesh_interfaces_path(const char *path, char *out, size_t cap)
{
  const i2m_format_t f = i2m_format_from_path(path);
  if (f != I2M_FORMAT_VTU && f != I2M_FORMAT_PVTU) return false;
  const char *dot = strrchr(path, '.');
  const int n = snprintf(out, cap, "%.*s.interfaces%s", (int)(dot - path), path, dot);
  return n > 0 && (size_t)n < cap;
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
  char companion[4096];
  I2M_CHECK(i2m_mesh_interfaces_path(path, companion, sizeof companion), I2M_ERR_ARG,
            "%s: path too long for its interfaces file", path);
  I2M_CALL(write_tets(m, path, wide, opts->compress));
  return write_interfaces(m, companion, wide, opts->compress);
}
