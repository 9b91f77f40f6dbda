/* Tests of the mesh writers (src/io) and of the independent checker (tools/check), whose
 * sources are compiled into this program (#include below) so that the checker's readers and
 * figures can be called directly (pieces of a .pvtu written by the VTU writer too).
 *
 * Meshes are built from small labelled voxel images: every labelled voxel is split into the
 * 6 positive tetrahedra of its Kuhn subdivision (all cubes cut along the same diagonal, so the
 * mesh is conforming), interface triangles are the faces between two labels or on the
 * boundary.  Such a mesh's interfaces are exactly the image's voxel staircase.
 *
 * Modes (environment variables):
 *   I2M_SAMPLE_OUT=DIR   write sample.vtu, sample.mesh, sample.msh, sample_ascii.msh and
 *                        sample.expect (counts, materials) into DIR and exit (used by
 *                        tests/scripts/test_writers_meshio.sh);
 *   I2M_BIG_MESH=IMAGE I2M_BIG_MESH_OUT=FILE [I2M_BIG_MESH_STEP=S]  build the voxel mesh of
 *                        IMAGE subsampled by S (default 6) in i and j, write FILE and exit
 *                        (a large mesh for timing i2m-check);
 *   otherwise            run the CUnit suite. */
#include "test_util.h"

#include "i2m/io.h"
#include "i2m/image.h"

#include "../../tools/check/ck_geom.c"
#include "../../tools/check/fidelity.c"
#include "../../tools/check/pvtu.c"
#include "../../tools/check/progress.c"
#include "../../tools/check/quality.c"
#include "../../tools/check/read_mesh.c"
#include "../../tools/check/validity.c"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ------------------------------------------------------------------ mesh builder */

/* The builders also run outside CUnit (sample modes): a failure there is fatal. */
#define BUILD_CHECK(c)                                                                        \
  do {                                                                                        \
    if (!(c)) {                                                                               \
      fprintf(stderr, "test_io_writers: %s:%d: %s failed: %s\n", __FILE__, __LINE__, #c,       \
              i2m_error_message());                                                           \
      abort();                                                                                \
    }                                                                                         \
  } while (0)

typedef struct {
  int64_t s[3];
  int64_t id; /* 4 t + f */
} tface_t;

static int cmp_tface(const void *a, const void *b)
{
  const tface_t *x = a, *y = b;
  for (int k = 0; k < 3; k++)
    if (x->s[k] != y->s[k]) return x->s[k] < y->s[k] ? -1 : 1;
  return (x->id > y->id) - (x->id < y->id);
}

/* Interface triangles of a tet mesh by sorting its faces (a test-side implementation). */
static void derive_tris(i2m_tetmesh_t *m)
{
  static const int F[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  int64_t nf = 4 * m->nt, n = 0;
  tface_t *f = malloc((size_t)nf * sizeof *f);
  for (int64_t id = 0; id < nf; id++) {
    const int32_t *tv = m->tet + 4 * (id / 4);
    int64_t s[3] = {tv[F[id % 4][0]], tv[F[id % 4][1]], tv[F[id % 4][2]]};
    for (int a = 0; a < 3; a++)
      for (int b = a + 1; b < 3; b++)
        if (s[b] < s[a]) {
          int64_t t = s[a];
          s[a] = s[b];
          s[b] = t;
        }
    memcpy(f[id].s, s, sizeof s);
    f[id].id = id;
  }
  qsort(f, (size_t)nf, sizeof *f, cmp_tface);
  free(m->tri);
  free(m->tri_label);
  m->tri = malloc((size_t)nf * 3 * sizeof *m->tri);
  m->tri_label = malloc((size_t)nf * 2 * sizeof *m->tri_label);
  for (int64_t i = 0; i < nf;) {
    int64_t j = i + 1;
    while (j < nf && memcmp(f[j].s, f[i].s, sizeof f[i].s) == 0) j++;
    int64_t id = f[i].id, lt = m->tet_label[id / 4];
    int64_t lo = j - i == 2 ? m->tet_label[f[i + 1].id / 4] : 0;
    if (lt != lo) {
      const int32_t *tv = m->tet + 4 * (id / 4);
      const int *fv = F[id % 4];
      int keep = i2m_label_ranks_below(lo, lt); /* normal from the higher label to the lower */
      m->tri[3 * n] = tv[fv[0]];
      m->tri[3 * n + 1] = tv[keep ? fv[1] : fv[2]];
      m->tri[3 * n + 2] = tv[keep ? fv[2] : fv[1]];
      m->tri_label[2 * n] = lt < lo ? lt : lo;
      m->tri_label[2 * n + 1] = lt < lo ? lo : lt;
      n++;
    }
    i = j;
  }
  m->ntri = n;
  free(f);
}

/* Voxel mesh of img (labels whose value is `drop` are left out), shifted in world space. */
static i2m_tetmesh_t *voxel_mesh(const i2m_image_t *img, int64_t drop, const double shift[3])
{
  const int64_t *n = img->n, c0 = n[0] + 1, c1 = n[1] + 1;
  int64_t ncorner = c0 * c1 * (n[2] + 1), nvox = 0;
  for (int64_t v = 0; v < n[0] * n[1] * n[2]; v++) {
    int64_t val = img->label_value[i2m_image_index(img, v)];
    nvox += val != 0 && val != drop;
  }
  int32_t *map = malloc((size_t)ncorner * sizeof *map);
  for (int64_t c = 0; c < ncorner; c++) map[c] = -1;
  i2m_tetmesh_t *m = NULL;
  BUILD_CHECK(i2m_tetmesh_create(0, 6 * nvox, 0, &m) == I2M_OK);
  m->xyz = realloc(m->xyz, (size_t)ncorner * 3 * sizeof *m->xyz);
  static const int P[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  int flip = i2m_image_handedness(img) < 0;
  int64_t t = 0;
  for (int64_t k = 0; k < n[2]; k++)
    for (int64_t j = 0; j < n[1]; j++)
      for (int64_t i = 0; i < n[0]; i++) {
        int64_t val = img->label_value[i2m_image_label_voxel(img, i, j, k)];
        if (val == 0 || val == drop) continue;
        for (int p = 0; p < 6; p++) {
          int64_t c[4][3] = {{i, j, k}};
          for (int s = 1; s < 4; s++) {
            memcpy(c[s], c[s - 1], sizeof c[s]);
            c[s][P[p][s - 1]]++;
          }
          int32_t ids[4];
          for (int s = 0; s < 4; s++) {
            int64_t key = (c[s][2] * c1 + c[s][1]) * c0 + c[s][0];
            if (map[key] < 0) {
              double g[3], w[3];
              for (int a = 0; a < 3; a++) g[a] = ((double)c[s][a] - 0.5) * img->spacing[a];
              i2m_image_grid_to_world(img, g, w);
              map[key] = (int32_t)m->nv;
              for (int a = 0; a < 3; a++) m->xyz[3 * m->nv + a] = w[a] + (shift ? shift[a] : 0);
              m->nv++;
            }
            ids[s] = map[key];
          }
          if ((p >= 3) != flip) { /* odd permutation (or a flipping direction matrix) */
            int32_t tmp = ids[1];
            ids[1] = ids[2];
            ids[2] = tmp;
          }
          memcpy(m->tet + 4 * t, ids, sizeof ids);
          m->tet_label[t++] = val;
        }
      }
  free(map);
  derive_tris(m);
  return m;
}

static i2m_image_t *make_image(const int64_t n[3], const double sp[3], const double *dir,
                               int64_t (*fn)(int64_t, int64_t, int64_t))
{
  int64_t *v = malloc((size_t)(n[0] * n[1] * n[2]) * sizeof *v);
  for (int64_t k = 0; k < n[2]; k++)
    for (int64_t j = 0; j < n[1]; j++)
      for (int64_t i = 0; i < n[0]; i++) v[(k * n[1] + j) * n[0] + i] = fn(i, j, k);
  double origin[3] = {10.0, -20.0, 5.0};
  i2m_image_t *img = NULL;
  i2m_err_t err = i2m_image_create_from_values(n, sp, origin, dir, v, &img);
  free(v);
  BUILD_CHECK(err == I2M_OK);
  return img;
}

/* A 2x2x2 cube of label 5 with a 1x2x1 block of label 9 on its +x side, label 1300000
 * (a 16-bit-overflowing value) as a single speck elsewhere. */
static int64_t two_labels(int64_t i, int64_t j, int64_t k)
{
  if (i >= 1 && i <= 2 && j >= 1 && j <= 2 && k >= 1 && k <= 2) return 5;
  if (i == 3 && j >= 1 && j <= 2 && k == 1) return 9;
  return 0;
}

static int64_t with_speck(int64_t i, int64_t j, int64_t k)
{
  if (i == 5 && j == 4 && k == 3) return 1300000;
  return two_labels(i, j, k);
}

static const int64_t N_SMALL[3] = {6, 5, 4};
static const double SP_SMALL[3] = {1.0, 0.5, 2.0};
static const double DIR_FLIP_Y[9] = {1, 0, 0, 0, -1, 0, 0, 0, 1};

static char tmpdir[256];

static const char *tmp_path(const char *name)
{
  static char buf[4][512];
  static int k;
  if (!tmpdir[0]) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/i2m_test_io_XXXXXX");
    CU_ASSERT_FATAL(mkdtemp(tmpdir) != NULL);
  }
  k = (k + 1) % 4;
  snprintf(buf[k], sizeof buf[k], "%s/%s", tmpdir, name);
  return buf[k];
}

/* ------------------------------------------------------------------ round trips */

typedef struct {
  int64_t v[4];
  int64_t lab[2];
} row_t;

static int cmp_row(const void *a, const void *b) { return memcmp(a, b, sizeof(row_t)); }

/* Sorted rows (vertex ids + labels) of tets or triangles, to compare regardless of order. */
static row_t *rows_tm(const i2m_tetmesh_t *m, int tris)
{
  int64_t n = tris ? m->ntri : m->nt;
  row_t *r = calloc((size_t)n + 1, sizeof *r);
  for (int64_t i = 0; i < n; i++) {
    for (int j = 0; j < (tris ? 3 : 4); j++) r[i].v[j] = tris ? m->tri[3 * i + j] : m->tet[4 * i + j];
    r[i].lab[0] = tris ? m->tri_label[2 * i] : m->tet_label[i];
    r[i].lab[1] = tris ? m->tri_label[2 * i + 1] : 0;
  }
  qsort(r, (size_t)n, sizeof *r, cmp_row);
  return r;
}

static row_t *rows_ck(const ck_mesh_t *m, int tris)
{
  int64_t n = tris ? m->ntri : m->nt;
  row_t *r = calloc((size_t)n + 1, sizeof *r);
  for (int64_t i = 0; i < n; i++) {
    for (int j = 0; j < (tris ? 3 : 4); j++) r[i].v[j] = tris ? m->tri[3 * i + j] : m->tet[4 * i + j];
    r[i].lab[0] = tris ? m->tri_label[2 * i] : m->tet_label[i];
    r[i].lab[1] = tris ? m->tri_label[2 * i + 1] : 0;
  }
  qsort(r, (size_t)n, sizeof *r, cmp_row);
  return r;
}

static void roundtrip(const i2m_tetmesh_t *m, const char *name, int expect_tris)
{
  const char *path = tmp_path(name);
  i2m_err_t err = i2m_mesh_write(m, path, NULL);
  if (err != I2M_OK) fprintf(stderr, "write: %s\n", i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  ck_mesh_t r;
  err = ck_mesh_read(path, &r);
  if (err != I2M_OK) fprintf(stderr, "read: %s\n", i2m_error_message());
  CU_ASSERT_FATAL(err == I2M_OK);
  CU_ASSERT_EQUAL(r.nv, m->nv);
  CU_ASSERT_EQUAL(r.nt, m->nt);
  CU_ASSERT(memcmp(r.xyz, m->xyz, (size_t)m->nv * 3 * sizeof(double)) == 0); /* exact */
  row_t *a = rows_tm(m, 0), *b = rows_ck(&r, 0);
  CU_ASSERT(memcmp(a, b, (size_t)m->nt * sizeof *a) == 0);
  free(a);
  free(b);
  CU_ASSERT_EQUAL(r.has_tri, expect_tris);
  if (expect_tris) {
    CU_ASSERT_EQUAL(r.ntri, m->ntri);
    CU_ASSERT(r.tri_labels_known);
    a = rows_tm(m, 1);
    b = rows_ck(&r, 1);
    CU_ASSERT(memcmp(a, b, (size_t)m->ntri * sizeof *a) == 0);
    free(a);
    free(b);
  }
  /* the checker finds the written mesh valid and its triangles equal to the derived ones */
  ck_validity_t v;
  ck_topo_t topo;
  CU_ASSERT_FATAL(ck_validity(&r, &v, &topo) == I2M_OK);
  if (!v.valid) fprintf(stderr, "%s: errors %s\n", name, v.errors);
  CU_ASSERT(v.valid);
  CU_ASSERT_EQUAL(v.interface_triangles, m->ntri);
  ck_topo_free(&topo);
  ck_mesh_free(&r);
}

static i2m_tetmesh_t *small_mesh(void)
{
  i2m_image_t *img = make_image(N_SMALL, SP_SMALL, DIR_FLIP_Y, with_speck);
  i2m_tetmesh_t *m = voxel_mesh(img, 0, NULL);
  i2m_image_destroy(&img);
  return m;
}

static void test_roundtrip_vtu(void)
{
  i2m_tetmesh_t *m = small_mesh();
  CU_ASSERT_EQUAL(m->nt, 6 * (8 + 2 + 1));
  roundtrip(m, "a.vtu", 0);
  i2m_tetmesh_destroy(&m);
}

static void test_roundtrip_medit(void)
{
  i2m_tetmesh_t *m = small_mesh();
  roundtrip(m, "a.mesh", 1);
  i2m_tetmesh_destroy(&m);
}

static void test_roundtrip_gmsh(void)
{
  i2m_tetmesh_t *m = small_mesh();
  unsetenv("I2M_MSH_ASCII");
  roundtrip(m, "a.msh", 1);
  setenv("I2M_MSH_ASCII", "1", 1);
  roundtrip(m, "ascii.msh", 1);
  unsetenv("I2M_MSH_ASCII");
  /* binary really is binary: the endianness mark follows the format line */
  FILE *f = fopen(tmp_path("a.msh"), "rb");
  char head[32] = {0};
  CU_ASSERT_FATAL(f != NULL);
  CU_ASSERT(fread(head, 1, 25, f) == 25);
  fclose(f);
  CU_ASSERT(memcmp(head, "$MeshFormat\n4.1 1 8\n\x01\0\0\0\n", 25) == 0);
  i2m_tetmesh_destroy(&m);
}

/* Labels beyond 32 bits: VTU switches its material array to Int64. */
static void test_vtu_wide_labels(void)
{
  i2m_tetmesh_t *m = small_mesh();
  m->tet_label[0] = (int64_t)1 << 40;
  derive_tris(m);
  roundtrip(m, "wide.vtu", 0);
  FILE *f = fopen(tmp_path("wide.vtu"), "rb");
  char buf[2048] = {0};
  CU_ASSERT(fread(buf, 1, sizeof buf - 1, f) > 0);
  fclose(f);
  CU_ASSERT(strstr(buf, "type=\"Int64\" Name=\"material\"") != NULL);
  i2m_tetmesh_destroy(&m);
}

static void test_write_errors(void)
{
  i2m_tetmesh_t *m = small_mesh();
  CU_ASSERT_EQUAL(i2m_mesh_write(m, tmp_path("x.obj"), NULL), I2M_ERR_ARG);
  CU_ASSERT(strstr(i2m_error_message(), "x.obj") != NULL);
  CU_ASSERT_EQUAL(i2m_mesh_write(m, "/nonexistent-dir/x.vtu", NULL), I2M_ERR_IO);
  CU_ASSERT(strstr(i2m_error_message(), "/nonexistent-dir/x.vtu") != NULL);
  const char *full = tmp_path("full.msh");
  if (symlink("/dev/full", full) == 0) { /* a full disk */
    CU_ASSERT_EQUAL(i2m_mesh_write(m, full, NULL), I2M_ERR_IO);
    CU_ASSERT(strstr(i2m_error_message(), "full.msh") != NULL);
    unlink(full);
  }
  m->tet_label[3] = 0; /* Gmsh physical tags must be positive */
  CU_ASSERT_EQUAL(i2m_mesh_write(m, tmp_path("zero.msh"), NULL), I2M_ERR_UNSUPPORTED);
  CU_ASSERT(strstr(i2m_error_message(), "Gmsh can't") != NULL);
  m->tet[5] = (int32_t)m->nv; /* a writer never emits dangling ids */
  CU_ASSERT_EQUAL(i2m_mesh_write(m, tmp_path("bad.vtu"), NULL), I2M_ERR_INTERNAL);
  i2m_tetmesh_destroy(&m);
}

/* Reader variants that other tools write: inline ascii arrays; appended data with UInt32
 * headers, Float32 points and Int32 connectivity; a truncated appended block. */
static void test_vtu_variants(void)
{
  const char *ascii =
      "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\">\n"
      "<UnstructuredGrid><Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n"
      "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n"
      "0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points>\n<Cells>\n"
      "<DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3</DataArray>\n"
      "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray>\n"
      "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">10</DataArray>\n</Cells>\n"
      "<CellData><DataArray type=\"Int16\" Name=\"material\" format=\"ascii\">-7</DataArray>"
      "</CellData>\n</Piece></UnstructuredGrid></VTKFile>\n";
  const char *path = tmp_path("ascii.vtu");
  FILE *f = fopen(path, "w");
  fputs(ascii, f);
  fclose(f);
  ck_mesh_t m;
  CU_ASSERT_FATAL(ck_mesh_read(path, &m) == I2M_OK);
  CU_ASSERT(m.nv == 4 && m.nt == 1 && m.tet_label[0] == -7 && m.xyz[11] == 1.0 && m.tet[3] == 3);
  ck_mesh_free(&m);
  /* appended, UInt32 headers, Float32 points, Int32 connectivity and offsets */
  char buf[1024];
  int n = snprintf(buf, sizeof buf,
      "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
      "<UnstructuredGrid><Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n"
      "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" "
      "offset=\"0\"/></Points><Cells>\n"
      "<DataArray type=\"Int32\" Name=\"connectivity\" format=\"appended\" offset=\"52\"/>\n"
      "<DataArray type=\"Int32\" Name=\"offsets\" format=\"appended\" offset=\"72\"/>\n"
      "<DataArray type=\"UInt8\" Name=\"types\" format=\"appended\" offset=\"80\"/>\n"
      "</Cells></Piece></UnstructuredGrid>\n<AppendedData encoding=\"raw\">_");
  unsigned char app[85];
  float pts[12] = {0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, 2};
  int32_t conn[4] = {0, 1, 2, 3}, off = 4;
  uint32_t h;
  h = 48; memcpy(app, &h, 4); memcpy(app + 4, pts, 48);      /* host is little-endian here */
  h = 16; memcpy(app + 52, &h, 4); memcpy(app + 56, conn, 16);
  h = 4; memcpy(app + 72, &h, 4); memcpy(app + 76, &off, 4);
  h = 1; memcpy(app + 80, &h, 4); app[84] = 10;
  const uint16_t one = 1;
  if (*(const unsigned char *)&one != 1) return; /* the bytes above are little-endian */
  path = tmp_path("u32.vtu");
  f = fopen(path, "wb");
  fwrite(buf, 1, (size_t)n, f);
  fwrite(app, 1, sizeof app, f);
  fputs("\n</AppendedData></VTKFile>\n", f);
  fclose(f);
  CU_ASSERT_FATAL(ck_mesh_read(path, &m) == I2M_OK);
  CU_ASSERT(m.nv == 4 && m.nt == 1 && m.tet_label[0] == 1 && m.xyz[11] == 2.0 && m.tet[2] == 2);
  ck_mesh_free(&m);
  /* the same with the connectivity block announcing more bytes than the file holds */
  h = 4000;
  memcpy(app + 52, &h, 4);
  f = fopen(path, "wb");
  fwrite(buf, 1, (size_t)n, f);
  fwrite(app, 1, sizeof app, f);
  fputs("\n</AppendedData></VTKFile>\n", f);
  fclose(f);
  CU_ASSERT_EQUAL(ck_mesh_read(path, &m), I2M_ERR_INPUT);
  CU_ASSERT(strstr(i2m_error_message(), "connectivity") != NULL);
}

/* ------------------------------------------------------------------ compressed VTU */

/* Labels 1..4 in slabs along x: a mesh whose connectivity (16 bytes a tet) fills more than one
 * 1 MiB compression block, the last one partial. */
static int64_t four_slabs(int64_t i, int64_t j, int64_t k)
{
  (void)j;
  (void)k;
  return 1 + i / 6;
}

static i2m_tetmesh_t *multi_block_mesh(void)
{
  static const int64_t n[3] = {24, 20, 32};
  i2m_image_t *img = make_image(n, SP_SMALL, DIR_FLIP_Y, four_slabs);
  i2m_tetmesh_t *m = voxel_mesh(img, 0, NULL);
  i2m_image_destroy(&img);
  return m;
}

static char *slurp(const char *path, size_t *len)
{
  char *buf = NULL;
  CU_ASSERT_FATAL(read_file(path, &buf, len) == I2M_OK);
  return buf;
}

static void spit(const char *path, const char *buf, size_t len)
{
  FILE *f = fopen(path, "wb");
  CU_ASSERT_FATAL(f != NULL);
  CU_ASSERT(fwrite(buf, 1, len, f) == len);
  fclose(f);
}

/* Byte offset in the file of appended array `name` (its header). */
static size_t appended_offset(const char *buf, const char *name)
{
  char key[96];
  snprintf(key, sizeof key, "Name=\"%s\"", name);
  const char *tag = strstr(buf, key), *off = tag ? strstr(tag, "offset=\"") : NULL;
  const char *app = strstr(buf, "<AppendedData");
  CU_ASSERT_FATAL(off && app && strchr(app, '_'));
  return (size_t)(strchr(app, '_') + 1 - buf) + (size_t)strtoull(off + 8, NULL, 10);
}

static void put_le64(char *p, uint64_t v)
{
  for (int b = 0; b < 8; b++) p[b] = (char)(unsigned char)(v >> (8 * b));
}

static uint64_t le64_at(const char *p)
{
  uint64_t v = 0;
  for (int b = 0; b < 8; b++) v |= (uint64_t)(unsigned char)p[b] << (8 * b);
  return v;
}

/* The interfaces file of m, read with the checker's VTU functions: its points are the
 * vertices the triangles use (in m's order), its triangles m's, renumbered, with their two
 * labels. */
static void check_interfaces_file(const i2m_tetmesh_t *m, const char *path)
{
  size_t len;
  char *buf = slurp(path, &len);
  vtu_t x = {buf, buf + len, path, NULL, NULL, 4, 0, 0, 0, 0, NULL};
  vtu_da_t das[16];
  int nda = 0;
  const char *xml_end;
  int64_t np, nc;
  CU_ASSERT_FATAL(vtu_header(&x, &xml_end, &np, &nc) == I2M_OK && vtu_scan(&x, xml_end, das, &nda, 16) == I2M_OK);
  CU_ASSERT(x.zlib);
  int32_t *used = malloc((size_t)m->nv * sizeof *used);
  int64_t nused = 0;
  for (int64_t v = 0; v < m->nv; v++) used[v] = -1;
  for (int64_t i = 0; i < 3 * m->ntri; i++) used[m->tri[i]] = 0;
  for (int64_t v = 0; v < m->nv; v++)
    if (used[v] == 0) used[nused++] = (int32_t)v; /* (nused <= v: rewrites entries already read) */
  CU_ASSERT_FATAL(np == nused && nc == m->ntri);
  double *xyz = malloc((size_t)(3 * np + 1) * sizeof *xyz);
  int64_t *conn = malloc((size_t)(3 * nc + 1) * sizeof *conn), *lab[2], *types = malloc((size_t)(nc + 1) * sizeof *types);
  lab[0] = malloc((size_t)(nc + 1) * sizeof **lab);
  lab[1] = malloc((size_t)(nc + 1) * sizeof **lab);
  CU_ASSERT_FATAL(vtu_array(&x, vtu_find(das, nda, VTU_SEC_POINTS, NULL), 3 * np, xyz, NULL) == I2M_OK);
  CU_ASSERT_FATAL(vtu_array(&x, vtu_find(das, nda, VTU_SEC_CELLS, "connectivity"), 3 * nc, NULL, conn) == I2M_OK);
  CU_ASSERT_FATAL(vtu_array(&x, vtu_find(das, nda, VTU_SEC_CELLS, "types"), nc, NULL, types) == I2M_OK);
  CU_ASSERT_FATAL(vtu_array(&x, vtu_find(das, nda, VTU_SEC_CELLDATA, "label_a"), nc, NULL, lab[0]) == I2M_OK);
  CU_ASSERT_FATAL(vtu_array(&x, vtu_find(das, nda, VTU_SEC_CELLDATA, "label_b"), nc, NULL, lab[1]) == I2M_OK);
  int64_t bad = 0;
  for (int64_t k = 0; k < np; k++) bad += memcmp(xyz + 3 * k, m->xyz + 3 * used[k], 3 * sizeof *xyz) != 0;
  for (int64_t i = 0; i < nc; i++) {
    bad += types[i] != 5 || lab[0][i] != m->tri_label[2 * i] || lab[1][i] != m->tri_label[2 * i + 1];
    for (int j = 0; j < 3; j++) bad += conn[3 * i + j] < 0 || conn[3 * i + j] >= np || used[conn[3 * i + j]] != m->tri[3 * i + j];
  }
  CU_ASSERT_EQUAL(bad, 0);
  free(used);
  free(xyz);
  free(conn);
  free(types);
  free(lab[0]);
  free(lab[1]);
  free(buf);
}

/* Compressed by default (several blocks, the last partial), raw on request: both read back
 * the same mesh, the compressed file is smaller, and the interfaces file holds the triangles. */
static void test_vtu_compressed(void)
{
  i2m_tetmesh_t *m = multi_block_mesh();
  CU_ASSERT_FATAL(16 * m->nt > (1 << 20) && (16 * m->nt) % (1 << 20) != 0); /* (Int32 connectivity) */
  roundtrip(m, "z.vtu", 0);
  i2m_write_opts_t raw = i2m_write_opts_default();
  raw.compress = false;
  CU_ASSERT_FATAL(i2m_mesh_write(m, tmp_path("r.vtu"), &raw) == I2M_OK);
  size_t zlen, rlen;
  char *z = slurp(tmp_path("z.vtu"), &zlen), *r = slurp(tmp_path("r.vtu"), &rlen);
  CU_ASSERT(strstr(z, "compressor=\"vtkZLibDataCompressor\"") != NULL);
  CU_ASSERT(strstr(r, "compressor=") == NULL);
  CU_ASSERT(zlen < rlen / 2);
  /* the connectivity's header: 2 blocks of 1 MiB, the last one partial */
  const char *h = z + appended_offset(z, "connectivity");
  CU_ASSERT(le64_at(h) == 2 && le64_at(h + 8) == (1 << 20) && le64_at(h + 16) == (uint64_t)(16 * m->nt) % (1 << 20));
  CU_ASSERT(strstr(z, "type=\"Int32\" Name=\"connectivity\"") != NULL && strstr(z, "type=\"Int32\" Name=\"offsets\"") != NULL);
  ck_mesh_t a, b;
  CU_ASSERT_FATAL(ck_mesh_read(tmp_path("r.vtu"), &a) == I2M_OK && ck_mesh_read(tmp_path("z.vtu"), &b) == I2M_OK);
  CU_ASSERT(a.nv == b.nv && a.nt == b.nt && memcmp(a.xyz, b.xyz, (size_t)a.nv * 3 * sizeof(double)) == 0);
  CU_ASSERT(memcmp(a.tet, b.tet, (size_t)a.nt * 4 * sizeof(int64_t)) == 0);
  CU_ASSERT(memcmp(a.tet_label, b.tet_label, (size_t)a.nt * sizeof(int64_t)) == 0);
  ck_mesh_free(&a);
  ck_mesh_free(&b);
  check_interfaces_file(m, tmp_path("z.interfaces.vtu"));
  /* the interfaces file as the checker reads a mesh: no tets, its triangles skipped */
  CU_ASSERT_FATAL(ck_mesh_read(tmp_path("r.interfaces.vtu"), &a) == I2M_OK);
  CU_ASSERT(a.nt == 0 && a.ignored_cells == m->ntri);
  ck_mesh_free(&a);
  free(z);
  free(r);
  i2m_tetmesh_destroy(&m);
}

/* Expects the checker to refuse path with I2M_ERR_INPUT and a message holding `what`. */
static void expect_refused(const char *path, const char *what)
{
  ck_mesh_t c;
  const i2m_err_t err = ck_mesh_read(path, &c);
  CU_ASSERT_EQUAL(err, I2M_ERR_INPUT);
  if (err == I2M_OK) ck_mesh_free(&c);
  else if (!strstr(i2m_error_message(), what)) fprintf(stderr, "expected '%s' in: %s\n", what, i2m_error_message());
  CU_ASSERT(err != I2M_OK && strstr(i2m_error_message(), what) != NULL);
}

/* Corrupt compressed files: a clear error each, never a crash. */
static void test_vtu_compressed_corrupt(void)
{
  i2m_tetmesh_t *m = multi_block_mesh();
  CU_ASSERT_FATAL(i2m_mesh_write(m, tmp_path("z.vtu"), NULL) == I2M_OK);
  size_t len;
  char *good = slurp(tmp_path("z.vtu"), &len), *bad = malloc(len);
  const char *path = tmp_path("bad.vtu");
  const size_t conn = appended_offset(good, "connectivity"), pts = appended_offset(good, "Points");
  /* a byte of the first connectivity block flipped */
  memcpy(bad, good, len);
  bad[conn + 8 * 5 + 100] ^= 0x55;
  spit(path, bad, len);
  expect_refused(path, "does not inflate");
  /* more blocks announced than the file can hold sizes for */
  memcpy(bad, good, len);
  put_le64(bad + pts, (uint64_t)1 << 40);
  spit(path, bad, len);
  expect_refused(path, "too short");
  /* a block size that does not add up to the array's size */
  memcpy(bad, good, len);
  put_le64(bad + conn + 8, (uint64_t)1 << 19);
  spit(path, bad, len);
  expect_refused(path, "compression header");
  /* a compressed size beyond the end of the data */
  memcpy(bad, good, len);
  put_le64(bad + conn + 8 * 4, (uint64_t)len);
  spit(path, bad, len);
  expect_refused(path, "truncated");
  /* the file cut in the middle of the data */
  spit(path, good, conn + 1000);
  expect_refused(path, "truncated");
  free(good);
  free(bad);
  i2m_tetmesh_destroy(&m);
}

/* ------------------------------------------------------------------ pieces (.pvtu) */

/* Tets t0 .. t1-1 of m as a piece: the vertices they use, renumbered, with global ids
 * offset + their index in m. */
static i2m_tetmesh_t *piece_of(const i2m_tetmesh_t *m, int64_t t0, int64_t t1, int64_t offset)
{
  int32_t *loc = malloc((size_t)m->nv * sizeof *loc);
  int64_t nv = 0;
  for (int64_t v = 0; v < m->nv; v++) loc[v] = -1;
  for (int64_t i = 4 * t0; i < 4 * t1; i++)
    if (loc[m->tet[i]] < 0) loc[m->tet[i]] = (int32_t)nv++;
  i2m_tetmesh_t *p = NULL;
  BUILD_CHECK(i2m_tetmesh_create(nv, t1 - t0, 0, &p) == I2M_OK);
  p->gid = malloc((size_t)nv * sizeof *p->gid);
  for (int64_t v = 0; v < m->nv; v++) {
    if (loc[v] < 0) continue;
    memcpy(p->xyz + 3 * loc[v], m->xyz + 3 * v, 3 * sizeof *p->xyz);
    p->gid[loc[v]] = offset + v;
  }
  for (int64_t i = 4 * t0; i < 4 * t1; i++) p->tet[i - 4 * t0] = loc[m->tet[i]];
  memcpy(p->tet_label, m->tet_label + t0, (size_t)(t1 - t0) * sizeof *p->tet_label);
  free(loc);
  return p;
}

/* Writes the two pieces with the VTU writer and pv.pvtu naming them; reads it back. */
static i2m_err_t write_read_pieces(i2m_tetmesh_t *const p[2], ck_mesh_t *c)
{
  CU_ASSERT_FATAL(i2m_mesh_write(p[0], tmp_path("pv_0.vtu"), NULL) == I2M_OK);
  CU_ASSERT_FATAL(i2m_mesh_write(p[1], tmp_path("pv_1.vtu"), NULL) == I2M_OK);
  FILE *f = fopen(tmp_path("pv.pvtu"), "w");
  CU_ASSERT_FATAL(f != NULL);
  fputs("<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\">\n"
        "<PUnstructuredGrid GhostLevel=\"0\">\n<Piece Source=\"pv_0.vtu\"/>\n"
        "<Piece Source=\"pv_1.vtu\"/>\n</PUnstructuredGrid>\n</VTKFile>\n", f);
  fclose(f);
  return ck_mesh_read(tmp_path("pv.pvtu"), c);
}

static i2m_err_t stitched_validity(const ck_mesh_t *c, ck_validity_t *v)
{
  ck_topo_t topo;
  i2m_err_t err = ck_validity(c, v, &topo);
  if (err == I2M_OK) err = ck_stitch_check(c, &topo, v);
  ck_topo_free(&topo);
  return err;
}

/* A mesh written as two pieces by the writer is the whole mesh again once stitched; a shared
 * vertex moved in one piece is a stitching error. */
static void test_pvtu_pieces(void)
{
  i2m_tetmesh_t *m = small_mesh();
  i2m_tetmesh_t *p[2] = {piece_of(m, 0, m->nt / 2, 100), piece_of(m, m->nt / 2, m->nt, 100)};
  ck_mesh_t c;
  ck_validity_t v;
  CU_ASSERT_FATAL(write_read_pieces(p, &c) == I2M_OK);
  CU_ASSERT_FATAL(c.stitch != NULL && c.stitch->npieces == 2);
  CU_ASSERT(c.nv == m->nv && c.nt == m->nt && strcmp(c.format, "pvtu") == 0);
  CU_ASSERT(c.stitch->vertices_before == p[0]->nv + p[1]->nv);
  CU_ASSERT(c.stitch->seam_vertices > 0 && c.stitch->seam_vertices == p[0]->nv + p[1]->nv - m->nv);
  for (int64_t k = 0; k < c.nv; k++)
    CU_ASSERT(memcmp(c.xyz + 3 * k, m->xyz + 3 * (c.gid[k] - 100), 3 * sizeof(double)) == 0);
  CU_ASSERT_FATAL(stitched_validity(&c, &v) == I2M_OK);
  CU_ASSERT(v.valid && c.stitch->seams_checked && c.stitch->one_sided_faces == 0);
  ck_mesh_free(&c);
  /* a vertex of piece 1 that piece 0 has too, one ulp away */
  int64_t shared = -1;
  for (int64_t i = 0; i < p[1]->nv && shared < 0; i++)
    for (int64_t j = 0; j < p[0]->nv; j++)
      if (p[0]->gid[j] == p[1]->gid[i]) shared = i;
  CU_ASSERT_FATAL(shared >= 0);
  p[1]->xyz[3 * shared] = nextafter(p[1]->xyz[3 * shared], INFINITY);
  CU_ASSERT_FATAL(write_read_pieces(p, &c) == I2M_OK);
  CU_ASSERT(c.stitch->coordinate_mismatches == 1);
  CU_ASSERT(strstr(c.stitch->first_mismatch, "in piece 0") != NULL);
  CU_ASSERT_FATAL(stitched_validity(&c, &v) == I2M_OK);
  CU_ASSERT(!v.valid && strstr(v.errors, "stitch_coordinate_mismatch") != NULL);
  ck_mesh_free(&c);
  i2m_tetmesh_destroy(&p[0]);
  i2m_tetmesh_destroy(&p[1]);
  i2m_tetmesh_destroy(&m);
}

/* ------------------------------------------------------------------ validity and quality */

static ck_mesh_t to_ck(const i2m_tetmesh_t *m)
{
  ck_mesh_t c;
  memset(&c, 0, sizeof c);
  c.nv = m->nv;
  c.nt = m->nt;
  c.xyz = malloc((size_t)m->nv * 3 * sizeof(double) + 1);
  memcpy(c.xyz, m->xyz, (size_t)m->nv * 3 * sizeof(double));
  c.tet = malloc((size_t)m->nt * 4 * sizeof(int64_t) + 1);
  c.tet_label = malloc((size_t)m->nt * sizeof(int64_t) + 1);
  for (int64_t i = 0; i < 4 * m->nt; i++) c.tet[i] = m->tet[i];
  memcpy(c.tet_label, m->tet_label, (size_t)m->nt * sizeof(int64_t));
  return c;
}

static void test_validity_defects(void)
{
  i2m_image_t *img = make_image(N_SMALL, SP_SMALL, NULL, two_labels);
  i2m_tetmesh_t *m = voxel_mesh(img, 0, NULL);
  ck_mesh_t c = to_ck(m);
  ck_validity_t v;
  ck_topo_t topo;
  CU_ASSERT_FATAL(ck_validity(&c, &v, &topo) == I2M_OK);
  CU_ASSERT(v.valid);
  CU_ASSERT_DOUBLE_EQUAL(v.total_volume, 10 * 1.0 * 0.5 * 2.0, 1e-12);
  CU_ASSERT_EQUAL(v.boundary_open_edges, 0);
  CU_ASSERT_EQUAL(v.interface_pairs, 3); /* 0|5, 0|9, 5|9 */
  ck_topo_free(&topo);
  /* inverted */
  int64_t t = c.tet[1];
  c.tet[1] = c.tet[2];
  c.tet[2] = t;
  CU_ASSERT_FATAL(ck_validity(&c, &v, &topo) == I2M_OK);
  CU_ASSERT(!v.valid && v.inverted == 1 && v.first_inverted == 0);
  CU_ASSERT(strstr(v.errors, "inverted") != NULL);
  ck_topo_free(&topo);
  c.tet[2] = c.tet[1];
  c.tet[1] = t;
  /* a tetrahedron repeated: its faces are shared 3 or 4 times */
  c.nt++;
  c.tet = realloc(c.tet, (size_t)c.nt * 4 * sizeof(int64_t));
  c.tet_label = realloc(c.tet_label, (size_t)c.nt * sizeof(int64_t));
  memcpy(c.tet + 4 * (c.nt - 1), c.tet + 4 * 7, 4 * sizeof(int64_t));
  c.tet_label[c.nt - 1] = 5;
  CU_ASSERT_FATAL(ck_validity(&c, &v, &topo) == I2M_OK);
  CU_ASSERT(!v.valid && v.nonmanifold_faces > 0);
  ck_topo_free(&topo);
  c.nt--;
  /* a duplicate and a dangling vertex */
  c.nv++;
  c.xyz = realloc(c.xyz, (size_t)c.nv * 3 * sizeof(double));
  memcpy(c.xyz + 3 * (c.nv - 1), c.xyz + 3 * 4, 3 * sizeof(double));
  CU_ASSERT_FATAL(ck_validity(&c, &v, &topo) == I2M_OK);
  CU_ASSERT(!v.valid && v.dangling == 1 && v.duplicate == 1 && v.first_dangling == c.nv - 1);
  ck_topo_free(&topo);
  c.nv--;
  /* out of range */
  c.tet[9] = c.nv + 3;
  CU_ASSERT_FATAL(ck_validity(&c, &v, &topo) == I2M_OK);
  CU_ASSERT(!v.valid && v.bad_index == 1 && v.first_bad_index == 2);
  ck_topo_free(&topo);
  ck_mesh_free(&c);
  i2m_tetmesh_destroy(&m);
  i2m_image_destroy(&img);
}

/* The exact orientation test decides nearly flat tets that double precision gets wrong. */
static void test_orient_exact(void)
{
  double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0}, d[3] = {0.5, 0.5, 0};
  CU_ASSERT_EQUAL(ck_orient3d(a, b, c, d), 0);
  d[2] = 1e-300;
  CU_ASSERT_EQUAL(ck_orient3d(a, b, c, d), 1);
  d[2] = -1e-300;
  CU_ASSERT_EQUAL(ck_orient3d(a, b, c, d), -1);
  /* points on a line of slope 1/3 carry rounding: x = 0.1 * k, exact sign by expansions */
  double p[3] = {0.1, 0.2, 0.3}, q[3] = {0.30000000000000004, 0.6000000000000001, 0.9000000000000001};
  double r[3] = {0.7, 1.4, 2.1}, s[3] = {12345.678, -0.5, 3.25};
  int o1 = ck_orient3d(p, q, r, s), o2 = ck_orient3d(q, p, r, s);
  CU_ASSERT_EQUAL(o1, -o2);
  double big[3] = {1e15, 1e15, 1e15}, e1[3] = {1e15 + 1, 1e15, 1e15}, e2[3] = {1e15, 1e15 + 1, 1e15},
         e3[3] = {1e15, 1e15, 1e15 + 1};
  CU_ASSERT_EQUAL(ck_orient3d(big, e1, e2, e3), 1);
}

static void test_quality_regular(void)
{
  ck_mesh_t c;
  memset(&c, 0, sizeof c);
  double x[12] = {1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1}; /* regular tet */
  int64_t tv[4] = {0, 1, 2, 3}, lab[1] = {7};
  c.nv = 4;
  c.nt = 1;
  c.xyz = x;
  c.tet = tv;
  c.tet_label = lab;
  if (ck_volume6(x, x + 3, x + 6, x + 9) < 0) {
    tv[1] = 2;
    tv[2] = 1;
  }
  ck_validity_t v;
  ck_topo_t topo;
  ck_quality_t q;
  CU_ASSERT_FATAL(ck_validity(&c, &v, &topo) == I2M_OK);
  CU_ASSERT(v.valid);
  CU_ASSERT_DOUBLE_EQUAL(v.total_volume, 8.0 / 3.0, 1e-12);
  CU_ASSERT_EQUAL(v.boundary_faces, 4);
  CU_ASSERT_FATAL(ck_quality(&c, &topo, 2.0, 30.0, &q) == I2M_OK);
  double dih = acos(1.0 / 3.0) * 180.0 / CK_PI;
  CU_ASSERT_DOUBLE_EQUAL(q.min_dihedral, dih, 1e-9);
  CU_ASSERT_DOUBLE_EQUAL(q.max_dihedral, dih, 1e-9);
  CU_ASSERT_EQUAL(q.dihedral_hist[70], 6);
  CU_ASSERT_DOUBLE_EQUAL(q.max_ratio, sqrt(6.0) / 4.0, 1e-12);
  CU_ASSERT_DOUBLE_EQUAL(q.min_planar_angle, 60.0, 1e-9);
  CU_ASSERT_EQUAL(q.planar_below_30, 0);
  /* Bounds met to within rounding: every angle is 60 and the ratio sqrt(6)/4 to a few ulps,
   * so those bounds are met exactly at the figure, and missed just beyond it. */
  CU_ASSERT_FATAL(ck_quality(&c, &topo, sqrt(6.0) / 4.0, 60.0, &q) == I2M_OK);
  CU_ASSERT_EQUAL(q.ratio_above_bound, 0);
  CU_ASSERT_EQUAL(q.planar_below_bound, 0);
  CU_ASSERT_FATAL(ck_quality(&c, &topo, sqrt(6.0) / 4.0 * (1 - 1e-9), 60.0 + 1e-9, &q) == I2M_OK);
  CU_ASSERT_EQUAL(q.ratio_above_bound, 1);
  CU_ASSERT_EQUAL(q.planar_below_bound, 4);
  CU_ASSERT(ck_meets_min(29.999999999999996, 30.0)); /* (a facet of the spine, kept at 30) */
  CU_ASSERT(!ck_meets_min(29.9999999, 30.0));
  CU_ASSERT(!ck_meets_min(NAN, 30.0) && !ck_meets_max(NAN, 2.0));
  CU_ASSERT(ck_meets_max(2.0000000000000004, 2.0) && !ck_meets_max(2.000001, 2.0));
  ck_topo_free(&topo);
}

/* ------------------------------------------------------------------ fidelity */

static void fidelity_of(const i2m_image_t *img, const i2m_tetmesh_t *m, ck_fidelity_t *f)
{
  ck_mesh_t c = to_ck(m);
  ck_validity_t v;
  ck_topo_t topo;
  CU_ASSERT_FATAL(ck_validity(&c, &v, &topo) == I2M_OK);
  CU_ASSERT(v.valid);
  CU_ASSERT_FATAL(ck_fidelity(&c, &topo, img, 1, f) == I2M_OK);
  ck_topo_free(&topo);
  ck_mesh_free(&c);
}

static const ck_label_t *label_of(const ck_fidelity_t *f, int64_t value)
{
  for (int i = 0; i < f->nlabels; i++)
    if (f->labels[i].value == value) return &f->labels[i];
  return NULL;
}

static void test_fidelity_exact(void)
{
  i2m_image_t *img = make_image(N_SMALL, SP_SMALL, DIR_FLIP_Y, with_speck);
  i2m_tetmesh_t *m = voxel_mesh(img, 0, NULL);
  ck_fidelity_t f;
  fidelity_of(img, m, &f);
  CU_ASSERT(f.two_sided.max < 1e-12);
  CU_ASSERT(f.mesh_to_image.max < 1e-12 && f.image_to_mesh.max < 1e-12);
  CU_ASSERT_EQUAL(f.missing_labels, 0);
  CU_ASSERT_EQUAL(f.extra_labels, 0);
  CU_ASSERT_EQUAL(f.nlabels, 3);
  const ck_label_t *a = label_of(&f, 5), *b = label_of(&f, 9), *s = label_of(&f, 1300000);
  CU_ASSERT_FATAL(a && b && s);
  CU_ASSERT_EQUAL(a->voxels, 8);
  CU_ASSERT_DOUBLE_EQUAL(a->image_volume, 8.0, 1e-12);
  CU_ASSERT(fabs(a->rel_error_pct) < 1e-9 && fabs(b->rel_error_pct) < 1e-9);
  CU_ASSERT_EQUAL(a->image_components, 1);
  CU_ASSERT_EQUAL(a->mesh_components, 1);
  CU_ASSERT_EQUAL(s->image_components, 1);
  CU_ASSERT_EQUAL(s->image_components_100, 0);
  CU_ASSERT_EQUAL(s->largest_component, 1);
  /* faces: cube 5 = 24 faces, block 9 = 10 faces (2 of them shared with 5), speck 6 */
  CU_ASSERT_EQUAL(f.image_faces, 24 + 8 + 6);
  ck_fidelity_free(&f);
  i2m_tetmesh_destroy(&m);
  i2m_image_destroy(&img);
}

static void test_fidelity_shift(void)
{
  i2m_image_t *img = make_image(N_SMALL, SP_SMALL, DIR_FLIP_Y, two_labels);
  const double shift[3] = {0.2, 0, 0};
  i2m_tetmesh_t *m = voxel_mesh(img, 0, shift);
  ck_fidelity_t f;
  fidelity_of(img, m, &f);
  CU_ASSERT_DOUBLE_EQUAL(f.mesh_to_image.max, 0.2, 1e-9);
  CU_ASSERT_DOUBLE_EQUAL(f.image_to_mesh.max, 0.2, 1e-9);
  CU_ASSERT_DOUBLE_EQUAL(f.two_sided.max, 0.2, 1e-9);
  CU_ASSERT_DOUBLE_EQUAL(f.two_sided.max / f.min_spacing, 0.4, 1e-9);
  CU_ASSERT(f.mesh_to_image.mean > 0.0 && f.mesh_to_image.mean < 0.2);
  ck_fidelity_free(&f);
  i2m_tetmesh_destroy(&m);
  /* a shift along world y (the flipped grid axis j, spacing 0.5) of 0.1 */
  const double shift_y[3] = {0, 0.1, 0};
  m = voxel_mesh(img, 0, shift_y);
  fidelity_of(img, m, &f);
  CU_ASSERT_DOUBLE_EQUAL(f.two_sided.max, 0.1, 1e-9);
  ck_fidelity_free(&f);
  i2m_tetmesh_destroy(&m);
  i2m_image_destroy(&img);
}

static void test_fidelity_missing_label(void)
{
  i2m_image_t *img = make_image(N_SMALL, SP_SMALL, NULL, with_speck);
  i2m_tetmesh_t *m = voxel_mesh(img, 1300000, NULL);
  ck_fidelity_t f;
  fidelity_of(img, m, &f);
  CU_ASSERT_EQUAL(f.missing_labels, 1);
  const ck_label_t *s = label_of(&f, 1300000);
  CU_ASSERT_FATAL(s != NULL);
  CU_ASSERT(s->in_image && !s->in_mesh);
  CU_ASSERT_DOUBLE_EQUAL(s->rel_error_pct, -100.0, 1e-9);
  /* the worst image face is the speck's, a one-voxel component next to the background */
  CU_ASSERT_EQUAL(f.worst_pair[0], 0);
  CU_ASSERT_EQUAL(f.worst_pair[1], 1300000);
  CU_ASSERT_EQUAL(f.worst_component[1], 1);
  CU_ASSERT_DOUBLE_EQUAL(f.worst_thinnest[1], 0.5, 1e-12); /* one voxel along j (spacing 0.5) */
  CU_ASSERT(f.image_to_mesh.max > 1.0);
  CU_ASSERT_DOUBLE_EQUAL(f.mesh_to_image.max, 0.0, 1e-12);
  ck_fidelity_free(&f);
  i2m_tetmesh_destroy(&m);
  i2m_image_destroy(&img);
}

/* Brute-force weighted q-quantile of (d, w) pairs: the smallest d whose cumulative weight
 * (pairs sorted by d) reaches q of the total. */
static double brute_quantile(const float *d, const float *w, int64_t n, double q)
{
  double total = 0;
  for (int64_t i = 0; i < n; i++) total += w[i];
  double best = INFINITY;
  for (int64_t i = 0; i < n; i++) { /* d[i] is the answer iff weight(<= d[i]) >= q total */
    double below = 0;
    for (int64_t j = 0; j < n; j++)
      if (d[j] <= d[i]) below += w[j];
    if (below >= q * total && d[i] < best) best = d[i];
  }
  return best;
}

/* Percentiles weigh each sample by its area and never separate a distance from its weight:
 * a side's own percentile, taken first, must not disturb the pooled one (it once did, by
 * reordering the distances in place). */
static void test_weighted_percentiles(void)
{
  enum { N0 = 1000, N1 = 600 };
  float *d0 = malloc(N0 * sizeof *d0), *w0 = malloc(N0 * sizeof *w0);
  float *d1 = malloc(N1 * sizeof *d1), *w1 = malloc(N1 * sizeof *w1);
  float all_d[N0 + N1], all_w[N0 + N1];
  CU_ASSERT_FATAL(d0 && w0 && d1 && w1);
  for (int i = 0; i < N0; i++) { /* shuffled 0..0.999, the far half ten times heavier */
    d0[i] = (float)((i * 7919) % N0) / N0;
    w0[i] = d0[i] < 0.5f ? 1.0f : 10.0f;
  }
  for (int i = 0; i < N1; i++) { /* 0.3..0.9, heavy near the top */
    d1[i] = 0.3f + 0.6f * (float)((i * 409) % N1) / N1;
    w1[i] = d1[i] > 0.8f ? 25.0f : 0.5f;
  }
  memcpy(all_d, d0, sizeof(float) * N0);
  memcpy(all_w, w0, sizeof(float) * N0);
  memcpy(all_d + N0, d1, sizeof(float) * N1);
  memcpy(all_w + N0, w1, sizeof(float) * N1);
  double want0 = brute_quantile(d0, w0, N0, 0.99), want1 = brute_quantile(d1, w1, N1, 0.99);
  double want = brute_quantile(all_d, all_w, N0 + N1, 0.99);
  pooled_t pool = {{NULL, NULL}, {NULL, NULL}, {0, 0}};
  ck_dist_t s0, s1;
  pooled_take(&pool, 0, &d0, &w0, N0, 0.0, &s0);
  pooled_take(&pool, 1, &d1, &w1, N1, 0.0, &s1);
  double tol = 2.0 / (1 << 20); /* histogram bins up to the largest distance (< 1) */
  CU_ASSERT_DOUBLE_EQUAL(s0.p99, want0, tol);
  CU_ASSERT_DOUBLE_EQUAL(s1.p99, want1, tol);
  CU_ASSERT_DOUBLE_EQUAL(weighted_quantile(&pool, 0, 1, 0.99), want, tol);
  /* the weights matter here: unweighted, the three would be 0.989, 0.893 and 0.983 */
  CU_ASSERT(want0 > 0.9935 && want1 > 0.8975 && want > 0.9905);
  pooled_free(&pool);
}

static int64_t two_blobs(int64_t i, int64_t j, int64_t k)
{
  if (k == 1 && j == 1 && (i == 0 || i == 1 || i == 4)) return 3; /* two components */
  if (k == 2 && j == 2 && i == 2) return 3;                        /* a third (diagonal) */
  return 0;
}

static void test_components(void)
{
  i2m_image_t *img = make_image(N_SMALL, SP_SMALL, NULL, two_blobs);
  i2m_tetmesh_t *m = voxel_mesh(img, 0, NULL);
  ck_fidelity_t f;
  fidelity_of(img, m, &f);
  const ck_label_t *l = label_of(&f, 3);
  CU_ASSERT_FATAL(l != NULL);
  CU_ASSERT_EQUAL(l->image_components, 3);
  CU_ASSERT_EQUAL(l->mesh_components, 3);
  CU_ASSERT_EQUAL(l->largest_component, 2);
  ck_fidelity_whole(&f, 1); /* every component one piece */
  CU_ASSERT_EQUAL(l->large_components, 3);
  CU_ASSERT_EQUAL(l->split_components, 0);
  ck_fidelity_free(&f);
  i2m_tetmesh_destroy(&m);
  i2m_image_destroy(&img);
}

/* A bar of label 7 along x; in bar_cut its third voxel is label 8. */
static int64_t bar(int64_t i, int64_t j, int64_t k)
{
  (void)i;
  return j == 2 && k == 1 ? 7 : 0;
}
static int64_t bar_cut(int64_t i, int64_t j, int64_t k) { return i == 2 && j == 2 && k == 1 ? 8 : bar(i, j, k); }

/* A mesh that cuts an image component in two: each piece stands for it (the circumcentres of
 * a voxel's six tets are the voxel's centre), so it counts as split, and as whole again with
 * a threshold above its size. */
static void test_components_split(void)
{
  i2m_image_t *img = make_image(N_SMALL, SP_SMALL, NULL, bar), *cut = make_image(N_SMALL, SP_SMALL, NULL, bar_cut);
  i2m_tetmesh_t *m = voxel_mesh(cut, 0, NULL);
  ck_fidelity_t f;
  fidelity_of(img, m, &f);
  const ck_label_t *l = label_of(&f, 7);
  CU_ASSERT_FATAL(l != NULL);
  CU_ASSERT_EQUAL(l->image_components, 1);
  CU_ASSERT_EQUAL(l->mesh_components, 2);
  ck_fidelity_whole(&f, 6);
  CU_ASSERT_EQUAL(l->large_components, 1);
  CU_ASSERT_EQUAL(l->split_components, 1);
  ck_fidelity_whole(&f, 7);
  CU_ASSERT_EQUAL(l->large_components, 0);
  CU_ASSERT_EQUAL(l->split_components, 0);
  ck_fidelity_free(&f);
  i2m_tetmesh_destroy(&m);
  i2m_image_destroy(&img);
  i2m_image_destroy(&cut);
}

/* ------------------------------------------------------------------ modes */

static int write_samples(const char *dir)
{
  i2m_tetmesh_t *m = small_mesh();
  char path[1024];
  const char *names[3] = {"sample.vtu", "sample.mesh", "sample.msh"};
  for (int i = 0; i < 3; i++) {
    snprintf(path, sizeof path, "%s/%s", dir, names[i]);
    if (i2m_mesh_write(m, path, NULL) != I2M_OK) goto fail;
  }
  setenv("I2M_MSH_ASCII", "1", 1);
  snprintf(path, sizeof path, "%s/sample_ascii.msh", dir);
  if (i2m_mesh_write(m, path, NULL) != I2M_OK) goto fail;
  unsetenv("I2M_MSH_ASCII");
  snprintf(path, sizeof path, "%s/sample.expect", dir);
  FILE *f = fopen(path, "w");
  if (!f) goto fail;
  fprintf(f, "points %lld\ntetra %lld\ntriangle %lld\nmaterials", (long long)m->nv,
          (long long)m->nt, (long long)m->ntri);
  for (int64_t t = 0; t < m->nt; t++) fprintf(f, " %lld", (long long)m->tet_label[t]);
  fprintf(f, "\n");
  fclose(f);
  i2m_tetmesh_destroy(&m);
  return 0;
fail:
  fprintf(stderr, "test_io_writers: %s\n", i2m_error_message());
  i2m_tetmesh_destroy(&m);
  return 1;
}

/* Voxel mesh of a real image subsampled by `step` in i and j (nearest voxel). */
static int write_big(const char *image, const char *out, int64_t step)
{
  i2m_image_t *img = NULL, *sub = NULL;
  if (i2m_image_read(image, &img) != I2M_OK) {
    fprintf(stderr, "test_io_writers: %s\n", i2m_error_message());
    return 1;
  }
  int64_t n[3] = {img->n[0] / step, img->n[1] / step, img->n[2]};
  int64_t *v = malloc((size_t)(n[0] * n[1] * n[2]) * sizeof *v);
  for (int64_t k = 0; k < n[2]; k++)
    for (int64_t j = 0; j < n[1]; j++)
      for (int64_t i = 0; i < n[0]; i++)
        v[(k * n[1] + j) * n[0] + i] =
            img->label_value[i2m_image_label_voxel(img, i * step + step / 2, j * step + step / 2, k)];
  double sp[3] = {img->spacing[0] * (double)step, img->spacing[1] * (double)step, img->spacing[2]};
  double g[3] = {(double)(step - 1) / 2 * img->spacing[0], (double)(step - 1) / 2 * img->spacing[1], 0};
  double o[3];
  i2m_image_grid_to_world(img, g, o);
  int rc = i2m_image_create_from_values(n, sp, o, &img->dir[0][0], v, &sub) != I2M_OK;
  free(v);
  if (!rc) {
    double t0 = i2m_wtime();
    i2m_tetmesh_t *m = voxel_mesh(sub, 0, NULL);
    double t1 = i2m_wtime();
    rc = i2m_mesh_write(m, out, NULL) != I2M_OK;
    if (rc) fprintf(stderr, "test_io_writers: %s\n", i2m_error_message());
    printf("%s: %lld vertices, %lld tets, %lld triangles; built in %.2f s, written in %.2f s\n",
           out, (long long)m->nv, (long long)m->nt, (long long)m->ntri, t1 - t0, i2m_wtime() - t1);
    i2m_tetmesh_destroy(&m);
  }
  i2m_image_destroy(&sub);
  i2m_image_destroy(&img);
  return rc;
}

static const test_case_t cases[] = {
    {"roundtrip_vtu", test_roundtrip_vtu},
    {"roundtrip_medit", test_roundtrip_medit},
    {"roundtrip_gmsh", test_roundtrip_gmsh},
    {"vtu_wide_labels", test_vtu_wide_labels},
    {"vtu_variants", test_vtu_variants},
    {"vtu_compressed", test_vtu_compressed},
    {"vtu_compressed_corrupt", test_vtu_compressed_corrupt},
    {"pvtu_pieces", test_pvtu_pieces},
    {"write_errors", test_write_errors},
    {"validity_defects", test_validity_defects},
    {"orient_exact", test_orient_exact},
    {"quality_regular", test_quality_regular},
    {"fidelity_exact", test_fidelity_exact},
    {"fidelity_shift", test_fidelity_shift},
    {"fidelity_missing_label", test_fidelity_missing_label},
    {"weighted_percentiles", test_weighted_percentiles},
    {"components", test_components}, {"components_split", test_components_split},
};

static void remove_tmpdir(void)
{
  if (!tmpdir[0]) return;
  const char *names[] = {"a.vtu", "a.mesh", "a.mesh.json", "a.msh", "ascii.msh", "wide.vtu", "bad.vtu",
                         "zero.msh", "x.obj", "full.msh", "ascii.vtu", "u32.vtu",
                         "pv_0.vtu", "pv_1.vtu", "pv.pvtu", "z.vtu", "r.vtu",
                         "a.interfaces.vtu", "wide.interfaces.vtu", "pv_0.interfaces.vtu",
                         "pv_1.interfaces.vtu", "z.interfaces.vtu", "r.interfaces.vtu"};
  for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) unlink(tmp_path(names[i]));
  rmdir(tmpdir);
}

int main(void)
{
  const char *out = getenv("I2M_SAMPLE_OUT");
  if (out) return write_samples(out);
  const char *big = getenv("I2M_BIG_MESH"), *big_out = getenv("I2M_BIG_MESH_OUT");
  if (big && big_out) {
    const char *st = getenv("I2M_BIG_MESH_STEP");
    return write_big(big, big_out, st ? atoll(st) : 6);
  }
  int rc = test_run_suite("io_writers", cases, (int)(sizeof cases / sizeof cases[0]));
  remove_tmpdir();
  return rc;
}
